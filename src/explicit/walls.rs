//! Planar walls of the driver and how they move.

use super::V3;
use serde::{Deserialize, Serialize};

/// How a wall moves along its normal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum WallControl {
    /// Does not move.
    Fixed,
    /// Moves with a prescribed normal velocity [m/s] (`Wall::velocity`, which a caller may change
    /// between steps, e.g. from a servo).
    Velocity,
    /// Moves towards `target` [m] (plane offset) at `speed` [m/s], then holds.
    Position { target: f64, speed: f64 },
    /// A body of mass `mass` [kg] pushed into the domain by `pressure` [Pa] over `Wall::area`,
    /// with viscous damping `damping` [kg/s]: `m_w s̈ = p A − F_w − γ_w ṡ` (Luding 2005 eq. 1),
    /// F_w the particles' normal force on it.
    Stress { pressure: f64, mass: f64, damping: f64 },
}

/// An infinite plane `n·x = offset`, particles on the side `n·x > offset`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Wall {
    /// Unit normal pointing into the domain [1].
    #[serde(with = "crate::io::serde_v3")]
    pub normal: V3,
    /// Plane offset along the normal [m].
    pub offset: f64,
    /// Normal velocity ṡ [m/s] (> 0 moves into the domain).
    pub velocity: f64,
    pub control: WallControl,
    /// Area over which a stress-controlled wall's pressure acts [m²].
    pub area: f64,
    /// Normal force the particles exert on the wall at the last force evaluation [N] (> 0 compressive).
    pub force: f64,
}

impl Wall {
    /// A fixed wall through `point` with inward normal `normal` (normalised here).
    pub fn new(normal: V3, point: V3) -> Self {
        let n = normal.normalize();
        Wall { normal: n, offset: n.dot(&point), velocity: 0.0, control: WallControl::Fixed, area: 1.0, force: 0.0 }
    }
    /// Mean normal stress on the wall, `force/area` [Pa].
    pub fn pressure(&self) -> f64 {
        self.force / self.area
    }
}

/// Moves the walls over one step under their control (step 2 of the module docs of
/// [`crate::explicit`]); a stress-controlled wall gets its first half kick `h = Δt/2` here.
pub(super) fn drift(walls: &mut [Wall], dt: f64, h: f64) {
    for w in walls.iter_mut() {
        match w.control {
            WallControl::Fixed => w.velocity = 0.0,
            WallControl::Velocity => w.offset += w.velocity * dt,
            WallControl::Position { target, speed } => {
                let rest = target - w.offset;
                let step = speed.abs() * dt;
                if rest.abs() <= step {
                    w.velocity = rest / dt;
                    w.offset = target;
                } else {
                    w.velocity = speed.abs() * rest.signum();
                    w.offset += w.velocity * dt;
                }
            }
            WallControl::Stress { pressure, mass, damping } => {
                let acc = (pressure * w.area - w.force - damping * w.velocity) / mass;
                w.velocity += h * acc;
                w.offset += w.velocity * dt;
            }
        }
    }
}

/// The second half kick of the stress-controlled walls (after the force evaluation).
pub(super) fn second_kick(walls: &mut [Wall], h: f64) {
    for w in walls.iter_mut() {
        if let WallControl::Stress { pressure, mass, damping } = w.control {
            // semi-implicit in the damping term for the second half kick
            let v = (w.velocity + h * (pressure * w.area - w.force) / mass) / (1.0 + h * damping / mass);
            w.velocity = v;
        }
    }
}
