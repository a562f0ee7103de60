//! Scenes written from code: the glTF 2.0 writer ([`gltf`]) and the project's test
//! scenes built with it ([`scenes`], `cargo xtask gen-scenes`). Tests that need a
//! scene of their own write it with the same writer, so every scene the project
//! checks itself on is plain glTF that any viewer opens.

pub mod gltf;
pub mod random;
pub mod scenes;
