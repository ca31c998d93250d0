//! propsim: one ray-tracing core, three simulators (images, room acoustics, radio coverage)
//! over the same OBJ scene and the same named materials.
// Unsafe code is denied everywhere but in the SIMD traversal (`core::traverse`), which allows
// it for intrinsics and its uninitialised stack, each use with a `SAFETY:` note.
#![deny(unsafe_code)]

pub mod acoustic;
mod cli;
pub mod core;
pub mod dist;
pub mod io;
pub mod render;
pub mod rf;
pub mod run;
pub mod scene;

pub use cli::command_line;
