//! propsim: one ray-tracing core, three simulators (images, room acoustics, radio coverage)
//! over the same OBJ scene and the same named materials.
#![forbid(unsafe_code)]

pub mod acoustic;
pub mod cli;
pub mod core;
pub mod dist;
pub mod io;
pub mod render;
pub mod rf;
pub mod scene;
