//! What the static cost ([`crate::cost::CostKind::Static`]) can determine, checked before a
//! run: an unknown it cannot see is refused by name rather than left to wander.
//!
//! At rest the residual of a free particle is `F_i(x, 0)/m_i + g`. Velocity-dependent forces
//! are 0 there, and multiplying every force at rest and every mass by one factor λ leaves the
//! residual unchanged: equilibrium frames determine stiffnesses, gains and masses only up to
//! that common scale (with gravity, the ratios `K/(m g)`), rest lengths and rest cosines
//! fully where the poses load the links differently.

use super::space::{ParameterSpace, Role};
use crate::error::CostError;
use cordis_core::Scene;

/// A force at rest scales with this unknown (a stiffness, a muscle's gain).
fn scales_force(name: &str, role: Role) -> bool {
    role == Role::Stiffness || name.ends_with(".gain")
}

/// `Err` naming the first unknown the static cost cannot determine.
pub(crate) fn check_unknowns(scene: &Scene, space: &ParameterSpace) -> Result<(), CostError> {
    let unknowns = &space.unknowns;
    if let Some(u) = unknowns
        .iter()
        .find(|u| matches!(u.role, Role::Damping | Role::Speed))
    {
        return Err(CostError::refused(
            &u.name,
            "the static cost weighs forces at rest (zero velocity), where this parameter acts \
             on nothing: give it a value, or use a cost of motion (short, horizon:H, long)",
        ));
    }
    let mass = unknowns.iter().find(|u| u.role == Role::Mass);
    let scale = unknowns.iter().find(|u| scales_force(&u.name, u.role));
    let gravity = scene.gravity != [0.0; 3];
    if let (Some(m), Some(k)) = (mass, scale) {
        return Err(CostError::refused(
            &m.name,
            format!(
                "unknown beside `{}`: equilibrium frames determine only their ratio K/m \
                 (scaling every force and mass alike leaves every pose at rest); give the \
                 masses or the stiffnesses",
                k.name
            ),
        ));
    }
    if let (Some(m), false) = (mass, gravity) {
        return Err(CostError::refused(
            &m.name,
            "without gravity a pose at rest balances link forces alone, which no mass enters",
        ));
    }
    // Without gravity, forces at rest balance each other only: a known stiffness (or gain)
    // must set their scale.
    let stiff_types = scene
        .types
        .iter()
        .filter(|t| t.kind.param_index("stiffness").is_some())
        .count();
    let unknown_stiff = unknowns
        .iter()
        .filter(|u| u.role == Role::Stiffness)
        .count();
    match (gravity, unknowns.iter().find(|u| u.role == Role::Stiffness)) {
        (false, Some(k)) if unknown_stiff == stiff_types => Err(CostError::refused(
            &k.name,
            "without gravity and with every stiffness unknown, poses at rest determine the \
             stiffnesses only up to a common factor: give one of them",
        )),
        _ => Ok(()),
    }
}
