//! Models and motions out, for the tools a researcher already uses (SPEC §7.3): MuJoCo's MJCF
//! ([`mjcf`]) and glTF 2.0 animations for Blender and three.js ([`gltf`]). Each writer is a
//! pure function from a scene (and a motion) to text; the CLI writes it atomically.

pub mod gltf;
pub mod mjcf;
pub mod mjcf_callback;

pub use gltf::to_gltf;
pub use mjcf::{mjcf_refusal, to_mjcf};
pub use mjcf_callback::callback_kinds;
