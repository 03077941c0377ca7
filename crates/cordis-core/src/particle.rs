//! Particles ("masses", thesis MAT): point masses in 3-D.

use crate::Param;

#[derive(Clone, Debug, PartialEq)]
pub struct Particle {
    /// Mass in kg; may be unknown (identified under a known total mass).
    pub mass: Param,
    /// Initial position x(0), m.
    pub pos: [f64; 3],
    /// Initial velocity v(0), m/s; sets x(-1) = x(0) - v0 dt.
    pub vel: [f64; 3],
    /// A fixed particle never moves: x(n+1) = x(n).
    pub fixed: bool,
    /// Group name, used by conditional link types.
    pub group: Option<String>,
    /// World name (`None` = the main world, see [`crate::world`]).
    pub world: Option<String>,
}

impl Particle {
    pub fn new(mass: f64, pos: [f64; 3]) -> Self {
        Particle {
            mass: Param::Known(mass),
            pos,
            vel: [0.0; 3],
            fixed: false,
            group: None,
            world: None,
        }
    }

    pub fn with_vel(mut self, vel: [f64; 3]) -> Self {
        self.vel = vel;
        self
    }

    pub fn fixed(mut self) -> Self {
        self.fixed = true;
        self
    }

    pub fn in_group(mut self, group: impl Into<String>) -> Self {
        self.group = Some(group.into());
        self
    }

    /// Puts the particle in the named world (`"main"` is the scene's own world).
    pub fn in_world(mut self, world: impl Into<String>) -> Self {
        let w = world.into();
        self.world = (w != crate::world::MAIN_WORLD).then_some(w);
        self
    }
}
