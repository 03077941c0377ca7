//! Cost functions of identification (SPEC §3, thesis §3.2.1): how far a candidate model's
//! predictions are from an observed trajectory.
//!
//! - [`CostKind`]: `short` (default), `horizon:H`, `long`, `progressive[:G]`,
//!   `harmonic[:EPS]`, `static` (equilibrium frames: [`CostKind::Static`]).
//! - [`Objective`]: a scene + trajectory + kind compiled once, evaluated on parameter vectors
//!   ([`Objective::evaluate`] with local costs, [`Objective::total`],
//!   [`Objective::evaluate_batch`] in parallel, [`Objective::report`]).
//! - [`LocalCost`]: the local costs written per particle, the position error or eq 3.3's
//!   neighbour distances.
//! - [`LinearShortCost`]: the short cost of linear-in-parameter scenes precomputed as quadratic
//!   forms; `Objective` uses it automatically.
//!
//! ```
//! use cordis_core::{LinkKind, LinkType, Particle, Scene};
//! use cordis_es::cost::{CostKind, Objective};
//! let mut scene = Scene::new(0.01);
//! scene.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
//! scene.add_particle(Particle::new(1.0, [1.5, 0.0, 0.0]));
//! scene.add_type(LinkType::new("rib", LinkKind::Spring).with("stiffness", 20.0).with("rest_length", 1.0));
//! scene.add_link("rib", &[0, 1]);
//! let traj = scene.simulate(50).unwrap();
//! let cost = Objective::new(&scene, &traj, "short".parse().unwrap()).unwrap();
//! let mut p = scene.param_values();
//! assert!(cost.report(&p).unwrap().total < 1e-20);
//! p[0] = 25.0; // a stiffer spring predicts worse
//! assert!(cost.report(&p).unwrap().rmse > 1e-6);
//! ```

mod batch;
mod equilibrium;
mod free_run;
mod geometry;
pub mod hidden;
pub(crate) mod kernels;
mod kind;
mod linear;
mod local;
mod objective;
mod observed;
mod rollout;
mod short;
mod sqrt_form;

pub use hidden::HiddenState;
pub use kernels::GEOMETRY_BUDGET_BYTES;
pub use kind::{CostKind, DEFAULT_GENERATIONS_TO_FULL, DEFAULT_HARMONIC_EPS};
pub use linear::{LinearShortCost, ThetaEntry};
pub use local::LocalCost;
pub use objective::{CostReport, CostScratch, Objective};
