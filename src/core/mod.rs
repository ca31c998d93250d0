//! The tracing core: rays, hits, meshes, spheres, the BVH, sampling and random streams,
//! the specular-path engine and the arrival-time bins.
//! It knows nothing of light, sound or radio.

pub mod accel;
pub mod bench;
pub mod complex;
pub mod convex;
pub mod fixed;
pub mod flat;
pub mod hit;
#[allow(unsafe_code)]
pub mod launcher;
pub mod leaf;
pub mod mesh;
pub mod near_segments;
#[allow(unsafe_code)]
pub mod queries;
pub mod ray;
pub mod rng;
pub mod sampling;
pub mod sdf;
pub mod shapes;
pub mod share;
pub mod spectrum;
pub mod specular;
pub mod sphere;
pub mod time_bins;
#[allow(unsafe_code)]
pub mod traverse;
pub mod triangle;
pub mod utd;
pub mod visibility;
pub mod wedges;

pub use accel::{Accel, BuildQuality, Instance, InstanceSet, MeshBvh, SphereSet};
pub use hit::{Hit, PrimitiveKind, SurfaceId};
pub use mesh::TriangleMesh;
pub use ray::Ray;
pub use share::Share;
pub use sphere::Sphere;
pub use time_bins::TimeBins;
pub use triangle::TriangleRt;
