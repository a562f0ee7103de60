//! One definition per parameter. A stage's parameters are declared once, with
//! [`params!`]: name, type, default, unit (in the doc comment) and accepted range.
//! The declaration is the stage binary's command line (clap, via
//! `#[command(flatten)]`), its `pipeline.toml` section (serde, unknown keys refused),
//! the arguments the runner passes ([`to_args`](crate#to_args)), and the checks that
//! refuse an out-of-range value (`--k 0`, a negative radius, NaN) with one line
//! naming the option or key. Choices are [`value_enum!`]s: one enum for the command
//! line, the file and the code.
//!
//! This crate knows nothing about photons or rendering.

use std::fmt;
use std::ops::Bound;

/// How an error names a parameter: as the command-line option or as the key of a
/// `pipeline.toml` section.
#[derive(Clone, Copy, Debug)]
pub enum Naming<'a> {
    /// `--gather-rays`.
    Cli,
    /// `render.gather_rays` (the section's name).
    File(&'a str),
}

impl Naming<'_> {
    /// The name of `field` (a Rust field name, also its key in the file).
    pub fn name(&self, field: &str) -> String {
        self.name_keyed(field, field)
    }

    /// The name of `field`, whose key in the file is `key`.
    pub fn name_keyed(&self, field: &str, key: &str) -> String {
        match self {
            Naming::Cli => format!("--{}", field.replace('_', "-")),
            Naming::File(section) => format!("{section}.{key}"),
        }
    }
}

/// A value a range check can read.
pub trait Value: PartialOrd + Copy + fmt::Display {
    /// False for NaN and infinities; integers are always finite.
    fn is_finite_value(&self) -> bool {
        true
    }
}
impl Value for u32 {}
impl Value for u64 {}
impl Value for usize {}
impl Value for f32 {
    fn is_finite_value(&self) -> bool {
        self.is_finite()
    }
}
impl Value for f64 {
    fn is_finite_value(&self) -> bool {
        self.is_finite()
    }
}

/// What a parameter accepts; displayed in errors ("at least 1", "in (0, 1]").
pub trait Accepts<T>: fmt::Display {
    /// True when `v` is acceptable.
    fn accepts(&self, v: &T) -> bool;
}

/// An interval of finite values.
#[derive(Clone, Copy, Debug)]
pub struct Range<T> {
    lo: Bound<T>,
    hi: Bound<T>,
}

/// `v >= lo`.
pub fn at_least<T>(lo: T) -> Range<T> {
    Range { lo: Bound::Included(lo), hi: Bound::Unbounded }
}

/// `v > lo`.
pub fn above<T>(lo: T) -> Range<T> {
    Range { lo: Bound::Excluded(lo), hi: Bound::Unbounded }
}

/// `lo <= v <= hi`.
pub fn between<T>(lo: T, hi: T) -> Range<T> {
    Range { lo: Bound::Included(lo), hi: Bound::Included(hi) }
}

/// `lo < v <= hi`.
pub fn above_up_to<T>(lo: T, hi: T) -> Range<T> {
    Range { lo: Bound::Excluded(lo), hi: Bound::Included(hi) }
}

impl<T: Value> Accepts<T> for Range<T> {
    fn accepts(&self, v: &T) -> bool {
        let lo = match self.lo {
            Bound::Included(l) => *v >= l,
            Bound::Excluded(l) => *v > l,
            Bound::Unbounded => true,
        };
        let hi = match self.hi {
            Bound::Included(h) => *v <= h,
            Bound::Excluded(h) => *v < h,
            Bound::Unbounded => true,
        };
        // NaN fails both comparisons; infinities are refused explicitly.
        lo && hi && v.is_finite_value()
    }
}

impl<T: fmt::Display> fmt::Display for Range<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.lo, &self.hi) {
            (Bound::Included(l), Bound::Unbounded) => write!(f, "at least {l}"),
            (Bound::Excluded(l), Bound::Unbounded) => write!(f, "finite and above {l}"),
            (Bound::Included(l), Bound::Included(h)) => write!(f, "in [{l}, {h}]"),
            (Bound::Excluded(l), Bound::Included(h)) => write!(f, "in ({l}, {h}]"),
            _ => write!(f, "in range"),
        }
    }
}

/// Accepts every value (choices, switches).
#[derive(Clone, Copy, Debug)]
pub struct Any;

impl<T> Accepts<T> for Any {
    fn accepts(&self, _: &T) -> bool {
        true
    }
}

impl fmt::Display for Any {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("any value")
    }
}

/// Declare a parameter struct once. Each field is
/// `/// doc with unit` `name: Type = default => check;` where `check` is an
/// [`Accepts`] (for example `at_least(1)`, `between(0.0, 1.0)`, `Any`). Generates
/// the struct (clap `Args` with `--kebab-name` options taking a value each, serde
/// with `deny_unknown_fields` and defaults), `Default`, `FIELDS`, `validate(Naming)`
/// and `to_args()`. Types must implement `Display` and `FromStr` the way clap and
/// `to_args` agree on (numbers, `bool` as `true`/`false`, [`value_enum!`]s).
///
/// `name as "key": Type = ...` gives the field another key in its file section
/// than its option's name: a method's own section can say `alpha` where the
/// command line, shared by every method, says `--sppm-alpha`.
#[macro_export]
macro_rules! params {
    (@key $field:ident) => { stringify!($field) };
    (@key $field:ident $key:literal) => { $key };
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $(
                $(#[doc = $doc:literal])*
                $field:ident $(as $key:literal)? : $ty:ty = $default:expr => $check:expr;
            )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq, clap::Args, serde::Deserialize, serde::Serialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct $name {
            $(
                $(#[doc = $doc])*
                #[arg(long, default_value_t = $default, action = clap::ArgAction::Set, allow_hyphen_values = true)]
                $(#[serde(rename = $key)])?
                pub $field: $ty,
            )*
        }

        impl Default for $name {
            fn default() -> Self {
                $name { $($field: $default,)* }
            }
        }

        impl $name {
            /// The keys of its file section (the fields' names unless given).
            pub const FIELDS: &'static [&'static str] = &[$($crate::params!(@key $field $($key)?)),*];

            /// Refuse a value outside its range, naming the option or key.
            pub fn validate(&self, naming: $crate::Naming) -> Result<(), String> {
                $(
                    let check = $check;
                    if !$crate::Accepts::accepts(&check, &self.$field) {
                        return Err(format!(
                            "{} = {} is out of range ({})",
                            naming.name_keyed(stringify!($field), $crate::params!(@key $field $($key)?)),
                            self.$field,
                            check
                        ));
                    }
                )*
                Ok(())
            }

            /// The command-line arguments that give every field its value.
            pub fn to_args(&self) -> Vec<String> {
                let mut v = Vec::new();
                $(
                    v.push(format!("--{}", stringify!($field).replace('_', "-")));
                    v.push(self.$field.to_string());
                )*
                v
            }
        }
    };
}

/// Declare a choice once: clap `ValueEnum` and serde both use the kebab-case
/// variant name (`Precomputed` is `precomputed`), and `Display` prints it.
#[macro_export]
macro_rules! value_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident {
            $(
                $(#[$vmeta:meta])*
                $variant:ident,
            )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, serde::Deserialize, serde::Serialize)]
        #[serde(rename_all = "kebab-case")]
        pub enum $name {
            $(
                $(#[$vmeta])*
                $variant,
            )*
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                let v = clap::ValueEnum::to_possible_value(self).expect("no variant is skipped");
                f.write_str(v.get_name())
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    value_enum! {
        /// A choice.
        pub enum Pick {
            /// One.
            First,
            /// Two.
            SecondOne,
        }
    }

    params! {
        /// Test parameters.
        pub struct P {
            /// A count.
            k: usize = 50 => at_least(1);
            /// A radius [m].
            radius_m: f32 = 0.1 => above(0.0);
            /// A fraction.
            fraction: f64 = 0.25 => above_up_to(0.0, 1.0);
            /// A switch.
            on: bool = true => Any;
            /// A choice.
            pick: Pick = Pick::SecondOne => Any;
            /// A field with its own key in the file.
            p_rate as "rate": f32 = 0.5 => between(0.0, 1.0);
        }
    }

    #[derive(Parser, Debug)]
    struct Cli {
        #[command(flatten)]
        p: P,
    }

    #[test]
    fn one_definition_gives_cli_file_defaults_and_args_that_agree() {
        let from_cli = Cli::try_parse_from(["x"]).unwrap().p;
        let from_file: P = toml::from_str("").unwrap();
        assert_eq!(from_cli, P::default());
        assert_eq!(from_file, P::default());
        let p = P { k: 7, radius_m: 0.1f32 + 1e-7, on: false, pick: Pick::First, ..P::default() };
        let args: Vec<String> = std::iter::once("x".to_string()).chain(p.to_args()).collect();
        assert_eq!(Cli::try_parse_from(&args).unwrap().p, p, "{args:?}");
        let text = format!("k = 7\nradius_m = {}\non = false\npick = \"first\"", p.radius_m);
        let file: P = toml::from_str(&text).unwrap();
        assert_eq!(file, p);
        assert!(toml::from_str::<P>("bogus = 1").is_err());
        assert_eq!(P::FIELDS, ["k", "radius_m", "fraction", "on", "pick", "rate"]);
        // A keyed field: --p-rate on the command line, rate in the file.
        let keyed = Cli::try_parse_from(["x", "--p-rate", "0.25"]).unwrap().p;
        assert_eq!(keyed, toml::from_str::<P>("rate = 0.25").unwrap());
        assert!(toml::from_str::<P>("p_rate = 0.25").is_err());
        let bad: P = toml::from_str("rate = 2").unwrap();
        assert_eq!(bad.validate(Naming::File("s")).unwrap_err(), "s.rate = 2 is out of range (in [0, 1])");
        assert!(bad.validate(Naming::Cli).unwrap_err().starts_with("--p-rate = 2"));
    }

    #[test]
    fn out_of_range_values_are_refused_naming_the_option_or_key() {
        for (args, want) in [
            (vec!["x", "--k", "0"], "--k = 0 is out of range (at least 1)"),
            (vec!["x", "--radius-m", "-1"], "--radius-m = -1 is out of range"),
            (vec!["x", "--radius-m", "NaN"], "--radius-m = NaN"),
            (vec!["x", "--radius-m", "inf"], "--radius-m = inf"),
            (vec!["x", "--fraction", "1.5"], "--fraction = 1.5 is out of range (in (0, 1])"),
            (vec!["x", "--fraction", "0"], "--fraction = 0 is out of range"),
        ] {
            let p = Cli::try_parse_from(&args).unwrap().p;
            let e = p.validate(Naming::Cli).unwrap_err();
            assert!(e.starts_with(want), "{e}");
        }
        let p: P = toml::from_str("k = 0").unwrap();
        assert_eq!(p.validate(Naming::File("render")).unwrap_err(), "render.k = 0 is out of range (at least 1)");
        assert!(P::default().validate(Naming::Cli).is_ok());
    }
}
