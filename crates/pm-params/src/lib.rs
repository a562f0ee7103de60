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
    /// `render.gather_rays` (the section's name); the key alone for `""`, the
    /// file's top level.
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
            Naming::File("") => key.to_string(),
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

    /// The value as a double (a user interface's limit).
    fn as_f64(self) -> f64;
}
impl Value for u32 {
    fn as_f64(self) -> f64 {
        self.into()
    }
}
impl Value for u64 {
    fn as_f64(self) -> f64 {
        self as f64
    }
}
impl Value for usize {
    fn as_f64(self) -> f64 {
        self as f64
    }
}
impl Value for f32 {
    fn is_finite_value(&self) -> bool {
        self.is_finite()
    }
    fn as_f64(self) -> f64 {
        self.into()
    }
}
impl Value for f64 {
    fn is_finite_value(&self) -> bool {
        self.is_finite()
    }
    fn as_f64(self) -> f64 {
        self
    }
}

/// The limits of a check as a user interface shows them: the lowest and highest
/// accepted value, `None` where unbounded (an open bound is given as its limit:
/// the interface keeps it, the check refuses it).
pub trait Bounds {
    /// (lowest, highest).
    fn bounds(&self) -> (Option<f64>, Option<f64>) {
        (None, None)
    }
}

impl<T: Value> Bounds for Range<T> {
    fn bounds(&self) -> (Option<f64>, Option<f64>) {
        let f = |b: &Bound<T>| match b {
            Bound::Included(v) | Bound::Excluded(v) => Some(v.as_f64()),
            Bound::Unbounded => None,
        };
        (f(&self.lo), f(&self.hi))
    }
}
/// The bounds of `check` on the values of one field (`values` says the type the
/// check is on).
pub fn bounds_of<'a, V: 'a, C: Accepts<V> + Bounds>(
    check: &C,
    _values: impl Iterator<Item = &'a V>,
) -> (Option<f64>, Option<f64>) {
    check.bounds()
}

impl Bounds for Any {}
impl Bounds for Valid {}

/// One parameter as a program that builds a user interface reads it (the
/// Blender add-on's settings): its key in the file section, its command-line
/// option, its documentation (with its unit), its Rust type, its default as the
/// option's text (none for an optional or repeatable one), the range it accepts
/// and, for a choice, its words.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Param {
    /// Key in the file section.
    pub key: &'static str,
    /// Command-line option, `--gather-rays`.
    pub option: String,
    /// The doc comment, one paragraph.
    pub doc: String,
    /// The field's Rust type (`u32`, `f32`, `bool`, a choice's path,
    /// `core::option::Option<f32>`).
    pub rust_type: &'static str,
    /// The default, as the option's text.
    pub default: Option<String>,
    /// What the check accepts, in words ("at least 1").
    pub accepts: String,
    /// Lowest accepted value.
    pub min: Option<f64>,
    /// Highest accepted value.
    pub max: Option<f64>,
    /// A choice's words (and `true`, `false` for a switch).
    pub choices: Vec<String>,
}

/// What a parameter accepts; displayed in errors ("at least 1", "in (0, 1]").
pub trait Accepts<T>: fmt::Display {
    /// True when `v` is acceptable.
    fn accepts(&self, v: &T) -> bool;

    /// Why `v` is refused, to follow "NAME = VALUE" in an error; `None` when it
    /// is accepted.
    fn refusal(&self, v: &T) -> Option<String> {
        (!self.accepts(v)).then(|| format!("is out of range ({self})"))
    }
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

/// Any finite value.
pub fn finite<T>() -> Range<T> {
    Range { lo: Bound::Unbounded, hi: Bound::Unbounded }
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
            (Bound::Unbounded, Bound::Unbounded) => write!(f, "finite"),
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

/// A value that knows its own limits (a medium's coefficients, a sun's angle):
/// what [`Valid`] asks.
pub trait SelfChecked {
    /// What is wrong with it, if anything.
    fn problem(&self) -> Option<String>;
}

/// Accepts a [`SelfChecked`] value with nothing wrong with it.
#[derive(Clone, Copy, Debug)]
pub struct Valid;

impl<T: SelfChecked> Accepts<T> for Valid {
    fn accepts(&self, v: &T) -> bool {
        v.problem().is_none()
    }

    fn refusal(&self, v: &T) -> Option<String> {
        v.problem().map(|p| format!("is refused: {p}"))
    }
}

impl fmt::Display for Valid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("valid")
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
///
/// A field without `= default` is an `Option<T>` (an option given at most once,
/// absent by default) or a `Vec<T>` (an option given any number of times, each
/// value one `T`); `check` then applies to each value, and `to_args` repeats the
/// option per value. `#[serde(...)]` attributes after the doc comment pass through
/// to the field: a list whose file form is a table (`[media.NAME]`) says how with
/// `#[serde(with = "...")]`; then `#[arg(...)]` ones, such as `value_name`.
#[macro_export]
macro_rules! params {
    (@key $field:ident) => { stringify!($field) };
    (@key $field:ident $key:literal) => { $key };
    (@default) => { Default::default() };
    (@default $default:expr) => { $default };
    // The values a field holds: itself, or each of an Option's or a Vec's.
    (@values $value:expr) => { $value.iter() };
    (@values $value:expr, $default:expr) => { std::iter::once(&$value) };
    // The struct, a field at a time: one with a default takes exactly one value.
    (@struct [$($meta:tt)*] $name:ident [$($done:tt)*]) => {
        $($meta)*
        #[derive(Clone, Debug, PartialEq, clap::Args, serde::Deserialize, serde::Serialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct $name {
            $($done)*
        }
    };
    (@struct $meta:tt $name:ident [$($done:tt)*]
        {$($attr:tt)*} $field:ident {$($key:literal)?} {$ty:ty} {$default:expr} $($rest:tt)*) => {
        $crate::params!(@struct $meta $name [$($done)*
            $($attr)*
            #[arg(long, default_value_t = $default, action = clap::ArgAction::Set, allow_hyphen_values = true)]
            $(#[serde(rename = $key)])?
            pub $field: $ty,
        ] $($rest)*);
    };
    (@struct $meta:tt $name:ident [$($done:tt)*]
        {$($attr:tt)*} $field:ident {$($key:literal)?} {$ty:ty} {} $($rest:tt)*) => {
        $crate::params!(@struct $meta $name [$($done)*
            $($attr)*
            #[arg(long, allow_hyphen_values = true)]
            $(#[serde(rename = $key)])?
            pub $field: $ty,
        ] $($rest)*);
    };
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $(
                $(#[doc = $doc:literal])*
                $(#[serde($($serde:tt)*)])*
                $(#[arg($($clap:tt)*)])*
                $field:ident $(as $key:literal)? : $ty:ty $(= $default:expr)? => $check:expr;
            )*
        }
    ) => {
        $crate::params!(@struct [$(#[$meta])*] $name []
            $(
                {$(#[doc = $doc])* $(#[serde($($serde)*)])* $(#[arg($($clap)*)])*} $field {$($key)?} {$ty} {$($default)?}
            )*
        );

        impl Default for $name {
            fn default() -> Self {
                $name { $($field: $crate::params!(@default $($default)?),)* }
            }
        }

        impl $name {
            /// The keys of its file section (the fields' names unless given).
            pub const FIELDS: &'static [&'static str] = &[$($crate::params!(@key $field $($key)?)),*];

            /// Refuse a value outside its range, naming the option or key.
            pub fn validate(&self, naming: $crate::Naming) -> Result<(), String> {
                $(
                    let check = $check;
                    for value in $crate::params!(@values self.$field $(, $default)?) {
                        if let Some(why) = $crate::Accepts::refusal(&check, value) {
                            return Err(format!(
                                "{} = {} {}",
                                naming.name_keyed(stringify!($field), $crate::params!(@key $field $($key)?)),
                                value,
                                why
                            ));
                        }
                    }
                )*
                Ok(())
            }

            /// Every parameter as a user interface reads it ([`Param`]), in
            /// declaration order.
            ///
            /// [`Param`]: $crate::Param
            pub fn schema() -> Vec<$crate::Param> {
                let cmd = <Self as clap::Args>::augment_args(clap::Command::new("schema"));
                let default = Self::default();
                let choices = |id: &str| -> Vec<String> {
                    cmd.get_arguments()
                        .find(|a| a.get_id() == id)
                        .map(|a| a.get_possible_values().iter().map(|v| v.get_name().to_string()).collect())
                        .unwrap_or_default()
                };
                vec![$({
                    let check = $check;
                    let values = $crate::params!(@values default.$field $(, $default)?);
                    let (min, max) = $crate::bounds_of(&check, values);
                    let doc: Vec<&str> = vec![$($doc.trim()),*];
                    $crate::Param {
                        key: $crate::params!(@key $field $($key)?),
                        option: format!("--{}", stringify!($field).replace('_', "-")),
                        doc: doc.join(" "),
                        rust_type: std::any::type_name::<$ty>(),
                        default: $crate::params!(@values default.$field $(, $default)?).next().map(|v| v.to_string()),
                        accepts: check.to_string(),
                        min,
                        max,
                        choices: choices(stringify!($field)),
                    }
                }),*]
            }

            /// The command-line arguments that give every field its value.
            pub fn to_args(&self) -> Vec<String> {
                let mut v = Vec::new();
                $(
                    for value in $crate::params!(@values self.$field $(, $default)?) {
                        v.push(format!("--{}", stringify!($field).replace('_', "-")));
                        v.push(value.to_string());
                    }
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

    /// A value with limits of its own: even numbers.
    #[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
    pub struct Even(u32);

    impl std::str::FromStr for Even {
        type Err = String;
        fn from_str(s: &str) -> Result<Even, String> {
            s.parse().map(Even).map_err(|_| format!("'{s}' is not a number"))
        }
    }

    impl fmt::Display for Even {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "{}", self.0)
        }
    }

    impl SelfChecked for Even {
        fn problem(&self) -> Option<String> {
            (self.0 % 2 == 1).then(|| format!("{} is odd", self.0))
        }
    }

    params! {
        /// Options given at most once or any number of times.
        pub struct Lists {
            /// An optional radius [m].
            radius: Option<f32> => above(0.0);
            /// Repeatable, with its own key in the file.
            #[serde(skip_serializing_if = "Vec::is_empty")]
            even as "evens": Vec<Even> => Valid;
            /// A plain one beside them.
            k: u32 = 3 => at_least(1);
        }
    }

    #[derive(Parser, Debug)]
    struct ListCli {
        #[command(flatten)]
        l: Lists,
    }

    #[test]
    fn optional_and_repeated_fields_agree_between_cli_file_and_args() {
        let none = ListCli::try_parse_from(["x"]).unwrap().l;
        assert_eq!(none, Lists::default());
        assert_eq!(none, toml::from_str::<Lists>("").unwrap());
        assert_eq!(none.to_args(), ["--k", "3"]);
        let cli = ListCli::try_parse_from(["x", "--radius", "0.5", "--even", "2", "--even", "4"]).unwrap().l;
        let file: Lists = toml::from_str("radius = 0.5\nevens = [2, 4]").unwrap();
        assert_eq!(cli, file);
        assert_eq!(cli.to_args(), ["--radius", "0.5", "--even", "2", "--even", "4", "--k", "3"]);
        let back: Vec<String> = std::iter::once("x".to_string()).chain(cli.to_args()).collect();
        assert_eq!(ListCli::try_parse_from(&back).unwrap().l, cli);
        assert_eq!(Lists::FIELDS, ["radius", "evens", "k"]);
        let odd = ListCli::try_parse_from(["x", "--even", "2", "--even", "3"]).unwrap().l;
        assert_eq!(odd.validate(Naming::Cli).unwrap_err(), "--even = 3 is refused: 3 is odd");
        let bad: Lists = toml::from_str("radius = -1.0").unwrap();
        assert_eq!(bad.validate(Naming::File("")).unwrap_err(), "radius = -1 is out of range (finite and above 0)");
        assert!(ListCli::try_parse_from(["x", "--radius", "1", "--radius", "2"]).is_err());
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

    /// The schema says what the declaration says: keys, options, defaults as the
    /// options' text, bounds, choices and the doc comment.
    #[test]
    fn the_schema_is_the_declaration() {
        let s = P::schema();
        let keys: Vec<&str> = s.iter().map(|p| p.key).collect();
        assert_eq!(keys, P::FIELDS);
        assert_eq!(
            (s[0].option.as_str(), s[0].default.as_deref(), s[0].min, s[0].max),
            ("--k", Some("50"), Some(1.0), None)
        );
        assert_eq!(s[1].doc, "A radius [m].");
        assert_eq!((s[2].min, s[2].max, s[2].accepts.as_str()), (Some(0.0), Some(1.0), "in (0, 1]"));
        assert_eq!(s[3].choices, ["true", "false"]);
        assert_eq!(
            (s[4].choices.clone(), s[4].default.as_deref()),
            (vec!["first".to_string(), "second-one".into()], Some("second-one"))
        );
        assert_eq!((s[5].key, s[5].option.as_str()), ("rate", "--p-rate"));
        let l = Lists::schema();
        assert_eq!((l[0].default.as_ref(), l[0].rust_type), (None, "core::option::Option<f32>"));
        assert_eq!(l[1].min, None);
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
