//! Scenes: the description (TOML + OBJ/MTL + materials) and the runtime world built from it.

pub mod builtin;
pub mod check;
pub mod density_grid;
pub mod desc;
pub mod dispersion;
pub mod error;
pub mod instances;
pub mod itu;
pub mod load;
pub mod materials;
pub mod media;
pub mod obj;
pub mod placement;
pub mod report;
pub mod sdf;
pub mod shapes;
pub mod world;

pub use check::{MeshReport, analyze};
pub use desc::SceneDesc;
pub use error::SceneError;
pub use instances::{InstanceDesc, SceneInstances};
pub use load::{LoadOptions, Scene, Surface, UpAxis, load};
pub use materials::{Material, MaterialLibrary};
pub use placement::{parse_point, parse_xy, place_inside};
pub use world::{FlatGeometry, World};
