//! The particle store, struct of arrays, indexed by dense `u32` ids (docs/design.md, "Data and
//! dispatch"). Positions are current positions [m]; the heat network reads radii, capacities and
//! temperatures; the explicit driver and the mechanics own velocities and rotations.

use nalgebra::Vector3;

/// Per-particle flags.
pub mod flags {
    /// Temperature prescribed by a heating profile (Dirichlet node of the heat network).
    pub const FIXED_TEMPERATURE: u8 = 1;
    /// Exchanges heat with the furnace (convection, radiation).
    pub const EXPOSED: u8 = 2;
    /// Excluded from the mechanics (rattler).
    pub const RATTLER: u8 = 4;
}

/// All particles of a scene.
#[derive(Debug, Clone, Default)]
pub struct Particles {
    /// Centre position [m].
    pub position: Vec<Vector3<f64>>,
    /// Translational velocity [m/s].
    pub velocity: Vec<Vector3<f64>>,
    /// Angular velocity [rad/s].
    pub angular_velocity: Vec<Vector3<f64>>,
    /// Accumulated rotation vector (small-rotation sum) [rad].
    pub rotation: Vec<Vector3<f64>>,
    /// Radius [m].
    pub radius: Vec<f64>,
    /// Mass [kg].
    pub mass: Vec<f64>,
    /// Moment of inertia of a solid sphere, (2/5) m r² [kg·m²].
    pub inertia: Vec<f64>,
    /// Heat capacity C_i = m_i c [J/K] (docs/heat-model.md (H1)).
    pub capacity: Vec<f64>,
    /// Temperature [K].
    pub temperature: Vec<f64>,
    /// Material index into the scene's material list.
    pub material: Vec<u16>,
    /// Bit flags, see [`flags`].
    pub flags: Vec<u8>,
}

impl Particles {
    pub fn len(&self) -> usize {
        self.radius.len()
    }

    pub fn is_empty(&self) -> bool {
        self.radius.is_empty()
    }

    /// Appends a particle at rest; mass, inertia and capacity from `density` [kg/m³] and
    /// `heat_capacity` [J/(kg·K)].
    pub fn push(&mut self, x: Vector3<f64>, r: f64, material: u16, density: f64, heat_capacity: f64, temperature: f64) -> u32 {
        let m = density * crate::units::sphere_volume(r);
        self.position.push(x);
        self.velocity.push(Vector3::zeros());
        self.angular_velocity.push(Vector3::zeros());
        self.rotation.push(Vector3::zeros());
        self.radius.push(r);
        self.mass.push(m);
        self.inertia.push(0.4 * m * r * r);
        self.capacity.push(m * heat_capacity);
        self.temperature.push(temperature);
        self.material.push(material);
        self.flags.push(0);
        (self.len() - 1) as u32
    }

    pub fn has_flag(&self, i: usize, flag: u8) -> bool {
        self.flags[i] & flag != 0
    }

    /// Axis-aligned bounding box of the spheres (centres ± radius) [m].
    pub fn bounding_box(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for (x, &r) in self.position.iter().zip(&self.radius) {
            lo = lo.inf(&x.add_scalar(-r));
            hi = hi.sup(&x.add_scalar(r));
        }
        (lo, hi)
    }

    /// Mean radius [m].
    pub fn mean_radius(&self) -> f64 {
        self.radius.iter().sum::<f64>() / self.len().max(1) as f64
    }
}
