//! # cordis-core
//!
//! Cordis-Anima mass-interaction networks: particles, a catalogue of link types, link
//! instances, and the CORDIS explicit two-step integrator (SPEC §2). A [`Scene`] is the
//! editable model; [`Plan`] is the scene compiled for speed (only the passes it uses, links
//! grouped by type, parameters in a flat vector); [`Simulator`] runs it.
//!
//! ```
//! use cordis_core::{LinkKind, LinkType, Particle, Scene};
//! let mut scene = Scene::new(0.01);
//! scene.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
//! scene.add_particle(Particle::new(1.0, [1.5, 0.0, 0.0]));
//! scene.add_type(LinkType::new("rib", LinkKind::Spring).with("stiffness", 20.0).with("rest_length", 1.0));
//! scene.add_link("rib", &[0, 1]);
//! let traj = scene.simulate(100).unwrap();
//! assert_eq!((traj.frames(), traj.particles()), (100, 2));
//! ```
#![forbid(unsafe_code)]

pub mod arg;
pub mod error;
pub mod examples;
pub mod export;
pub mod forces;
pub mod from_markers;
pub mod io;
mod link_kind;
mod link_type;
mod observations;
mod param;
mod param_layout;
mod particle;
pub mod plan;
pub mod runaway;
mod scene;
pub mod scene_json;
pub mod signal;
mod simulator;
pub mod stability;
pub mod thesis;
mod trajectory;
pub mod world;

pub use error::{CordisError, Result};
pub use link_kind::LinkKind;
pub use link_type::{Coupling, Link, LinkType, OptionalParam};
pub use observations::Observations;
pub use param::{Bounds, Param};
pub use param_layout::ParamLayout;
pub use particle::Particle;
pub use plan::Plan;
pub use runaway::Runaway;
pub use scene::Scene;
pub use signal::{Shape, Signal};
pub use simulator::Simulator;
pub use stability::{stability, StabilityReport, StabilityScratch};
pub use trajectory::Trajectory;
pub use world::World;

/// 3-vector of f64 (positions in m, velocities in m/s, forces in N).
pub type Vec3 = nalgebra::Vector3<f64>;
