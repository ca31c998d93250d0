//! Room acoustics: sound rays from point sources through a closed room to sphere receivers,
//! merged with image sources for the early specular part, giving energy histograms, impulse
//! responses and ISO 3382-1 parameters.

pub mod air;
pub mod ambisonics;
pub mod auralize;
pub mod balloon;
pub mod diffraction;
pub mod directions;
pub mod directivity;
pub mod edge_scattering;
pub mod hrtf;
pub mod image_source;
pub mod impulse_response;
pub mod job;
pub mod metrics;
pub mod options;
pub mod output;
pub mod ray_diffraction;
pub mod room;
pub mod simulate;
pub mod spatial;
pub mod tracer;

pub use air::Air;
pub use job::{Plan, execute, plan};
pub use options::AcousticOptions;
pub use simulate::{
    AcousticResult, AcousticSettings, NO_AIR, PairResult, ReceiverSpec, SourceSpec, check, check_points,
    scene_points, simulate, simulate_on,
};
