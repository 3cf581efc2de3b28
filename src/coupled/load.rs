//! Applied load of a compact run (`[load]`, docs/pressure.md): uniaxial stress on one face (hot
//! pressing, the opposite principal plane held) or isostatic pressure on every outer face, each
//! following a stress profile in time. The load enters the bonded solve as nodal forces on the
//! particles of the loaded faces (P1), (P2); the axial force it causes in each bond is the
//! contact's normal force (P3), which shifts the contact's GB potentials (docs/diffusion7.md
//! (M11)); the macroscopic stress of the compact is (P4).

use crate::error::ConfigError;
use crate::mechanics::NodalLoad;
use crate::scene::case::LoadSpec;
use nalgebra::Vector3;

/// How the load acts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoadMode {
    /// Compressive stress on the far face of one axis (0 = x, 1 = y, 2 = z).
    Uniaxial(usize),
    /// The same compressive stress on the far faces of all three axes (the near faces are the
    /// held principal planes, which take the opposite loads as reactions).
    Isostatic,
}

impl LoadMode {
    /// The loaded axes.
    pub fn axes(&self) -> Vec<usize> {
        match *self {
            LoadMode::Uniaxial(a) => vec![a],
            LoadMode::Isostatic => vec![0, 1, 2],
        }
    }
}

/// A piecewise-linear stress history σ(t) [Pa] (compressive positive).
#[derive(Debug, Clone, PartialEq)]
pub struct StressProfile {
    times: Vec<f64>,
    values: Vec<f64>,
}

impl StressProfile {
    /// From `[[t s, σ Pa], …]` rows, times strictly increasing, every σ in the range of `load.stress`.
    pub fn from_table(rows: &[[f64; 2]]) -> Result<Self, ConfigError> {
        if rows.is_empty() {
            return Err(ConfigError::invalid("load.stress_table: needs at least one [time s, stress Pa] row"));
        }
        let stress = crate::config::ranges::lookup("load.stress").ok_or_else(|| ConfigError::invalid("internal: load.stress has no range"))?;
        let time =
            crate::config::ranges::lookup("load.stress_table.time").ok_or_else(|| ConfigError::invalid("internal: load.stress_table.time has no range"))?;
        let mut times = Vec::with_capacity(rows.len());
        let mut values = Vec::with_capacity(rows.len());
        for (k, r) in rows.iter().enumerate() {
            time.check(&format!("load.stress_table[{k}] time"), r[0])?;
            if let Some(&last) = times.last()
                && (r[0] < last || r[0] == last && (k < 2 || times[k - 2] == last))
            {
                return Err(ConfigError::invalid(format!(
                    "load.stress_table[{k}]: time {} s is not after the previous row's {} s (two rows with the same time make a jump, but not at the first row; three may not)",
                    r[0], last
                )));
            }
            stress.check(&format!("load.stress_table[{k}] stress"), r[1])?;
            times.push(r[0]);
            values.push(r[1]);
        }
        Ok(StressProfile { times, values })
    }

    /// A constant stress [Pa].
    pub fn constant(v: f64) -> Result<Self, ConfigError> {
        crate::config::check("load.stress", v)?;
        Ok(StressProfile { times: vec![0.0], values: vec![v] })
    }

    /// σ(t) [Pa]: linear between rows, the first value before the first row, the last after the
    /// last; at a jump (two rows with the same time) the first row's value, the second's after it.
    pub fn at(&self, t: f64) -> f64 {
        let n = self.times.len();
        if t <= self.times[0] {
            return self.values[0];
        }
        if t >= self.times[n - 1] {
            return if n >= 2 && t == self.times[n - 1] && self.times[n - 2] == t { self.values[n - 2] } else { self.values[n - 1] };
        }
        let k = self.times.partition_point(|&x| x <= t);
        if k >= 2 && self.times[k - 2] == t {
            return self.values[k - 2];
        }
        let (t0, t1, v0, v1) = (self.times[k - 1], self.times[k], self.values[k - 1], self.values[k]);
        v0 + (v1 - v0) * (t - t0) / (t1 - t0)
    }

    /// This history up to `t` [s], then `stress` [Pa] held from `t` on (a jump at `t` unless `t`
    /// is 0): what `set_applied_stress` makes of it; [`StressProfile::rows`] is its table.
    pub fn hold_from(&self, t: f64, stress: f64) -> Result<Self, ConfigError> {
        if !(t.is_finite() && t > 0.0) {
            return Self::constant(stress);
        }
        crate::config::check("load.stress", stress)?;
        let k = self.times.partition_point(|&x| x < t);
        let mut times = self.times[..k].to_vec();
        let mut values = self.values[..k].to_vec();
        if k == 0 {
            // no row before t: the history was its first value until then (a table's first row)
            times.push(0.0);
            values.push(self.values[0]);
        }
        times.extend([t, t]);
        values.extend([self.at(t), stress]);
        Ok(StressProfile { times, values })
    }

    /// The history as `[time s, stress Pa]` rows (`load.stress_table`).
    pub fn rows(&self) -> Vec<[f64; 2]> {
        self.times.iter().zip(&self.values).map(|(&a, &b)| [a, b]).collect()
    }

    /// The largest stress of the history [Pa].
    pub fn max(&self) -> f64 {
        self.values.iter().copied().fold(0.0, f64::max)
    }
}

/// The validated `[load]` section.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadSettings {
    pub mode: LoadMode,
    pub stress: StressProfile,
    /// (P5) largest mean normal stress |F_n|/(π a²) passed to a contact's diffusion model [Pa]
    /// (∞: no limit).
    pub contact_stress_limit: f64,
}

impl LoadSettings {
    /// `None` for no section or `mode = "none"`; errors name the key, the value and what is allowed.
    pub fn from_spec(spec: Option<&LoadSpec>) -> Result<Option<LoadSettings>, ConfigError> {
        let Some(s) = spec else { return Ok(None) };
        let axis = |a: Option<&str>| -> Result<usize, ConfigError> {
            match a.unwrap_or("z") {
                "x" => Ok(0),
                "y" => Ok(1),
                "z" => Ok(2),
                o => Err(ConfigError::invalid(format!("load.axis = \"{o}\": expected \"x\", \"y\" or \"z\""))),
            }
        };
        let mode = match s.mode.as_str() {
            "none" => {
                if s.stress.is_some() || s.stress_table.is_some() || s.axis.is_some() || s.contact_stress_limit.is_some() {
                    return Err(ConfigError::inconsistent("load.mode", "\"none\" takes no axis, stress, stress_table or contact_stress_limit"));
                }
                return Ok(None);
            }
            "uniaxial" => LoadMode::Uniaxial(axis(s.axis.as_deref())?),
            "isostatic" => {
                if s.axis.is_some() {
                    return Err(ConfigError::inconsistent("load.axis", "an isostatic load acts on every face: give no axis"));
                }
                LoadMode::Isostatic
            }
            o => return Err(ConfigError::invalid(format!("load.mode = \"{o}\": expected \"none\", \"uniaxial\" or \"isostatic\""))),
        };
        let stress = match (s.stress, &s.stress_table) {
            (Some(v), None) => StressProfile::constant(v)?,
            (None, Some(t)) => StressProfile::from_table(t)?,
            _ => return Err(ConfigError::inconsistent("load.stress", "give exactly one of load.stress (Pa) and load.stress_table ([[time s, stress Pa], …])")),
        };
        let contact_stress_limit = crate::config::check_opt("load.contact_stress_limit", s.contact_stress_limit)?.unwrap_or(f64::INFINITY);
        Ok(Some(LoadSettings { mode, stress, contact_stress_limit }))
    }
}

/// The load's state in a run (a checkpoint carries [`LoadCheckpoint`]).
#[derive(Debug, Clone)]
pub struct LoadState {
    pub settings: LoadSettings,
    /// Nodal forces applied to the incremental bonded solve so far (the sum of the increments) [N].
    pub applied: Vec<Vector3<f64>>,
    /// Per contact, the force on A exerted by B through the bond in the last load-distribution
    /// solve (P3), global axes [N].
    pub contact_force: Vec<Vector3<f64>>,
    /// Per contact, the axial (normal) force of that solve, compressive positive [N].
    pub contact_normal: Vec<f64>,
    /// Total applied force Σ|F_i| of that solve [N] (0: none yet).
    pub ref_total: f64,
    /// Contacts at that solve, and its step.
    pub ref_contacts: usize,
    pub ref_step: u64,
    /// Load-distribution solves so far [1].
    pub solves: u64,
}

/// What a checkpoint keeps of a [`LoadState`].
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct LoadCheckpoint {
    pub applied: Vec<[f64; 3]>,
    pub contact_force: Vec<[f64; 3]>,
    pub contact_normal: Vec<f64>,
    pub ref_total: f64,
    pub ref_contacts: usize,
    pub ref_step: u64,
    pub solves: u64,
}

/// The load distribution is re-solved at least every this many steps (and whenever contacts
/// appear); in between, the forces of the last solve are scaled by the total applied force.
pub const REDISTRIBUTE_EVERY: u64 = 25;

impl LoadState {
    pub fn new(settings: LoadSettings, n: usize) -> Self {
        LoadState {
            settings,
            applied: vec![Vector3::zeros(); n],
            contact_force: Vec::new(),
            contact_normal: Vec::new(),
            ref_total: 0.0,
            ref_contacts: 0,
            ref_step: 0,
            solves: 0,
        }
    }

    pub fn to_checkpoint(&self) -> LoadCheckpoint {
        let v = |x: &Vector3<f64>| [x.x, x.y, x.z];
        LoadCheckpoint {
            applied: self.applied.iter().map(v).collect(),
            contact_force: self.contact_force.iter().map(v).collect(),
            contact_normal: self.contact_normal.clone(),
            ref_total: self.ref_total,
            ref_contacts: self.ref_contacts,
            ref_step: self.ref_step,
            solves: self.solves,
        }
    }

    pub fn restore(&mut self, ck: &LoadCheckpoint) {
        let v = |x: &[f64; 3]| Vector3::new(x[0], x[1], x[2]);
        self.applied = ck.applied.iter().map(v).collect();
        self.contact_force = ck.contact_force.iter().map(v).collect();
        self.contact_normal = ck.contact_normal.clone();
        self.ref_total = ck.ref_total;
        self.ref_contacts = ck.ref_contacts;
        self.ref_step = ck.ref_step;
        self.solves = ck.solves;
    }
}

/// (P1), (P2): the nodal forces of stress `sigma` [Pa] on the loaded faces. On each loaded axis a
/// the total force σ·A_a, A_a the product of the two other current extents [m²], is shared among
/// the particles of the far layer `far[a]` in proportion to their projected areas π r_i² and
/// pushes them towards the principal plane (−e_a). With free planes (`free`), the near layer
/// `near[a]` takes the opposite forces, so the load is self-equilibrated.
pub fn nodal_forces(
    mode: LoadMode,
    sigma: f64,
    extents: &Vector3<f64>,
    radii: &[f64],
    far: &[Vec<u32>; 3],
    near: &[Vec<u32>; 3],
    free: bool,
) -> Vec<Vector3<f64>> {
    let mut f = vec![Vector3::zeros(); radii.len()];
    if sigma == 0.0 {
        return f;
    }
    for a in mode.axes() {
        let area = extents[(a + 1) % 3] * extents[(a + 2) % 3];
        let total = sigma * area;
        let layers: Vec<(&Vec<u32>, f64)> = if free { vec![(&far[a], -1.0), (&near[a], 1.0)] } else { vec![(&far[a], -1.0)] };
        for (layer, sign) in layers {
            let w: f64 = layer.iter().map(|&i| radii[i as usize] * radii[i as usize]).sum();
            if w <= 0.0 {
                continue;
            }
            for &i in layer {
                let r = radii[i as usize];
                f[i as usize][a] += sign * total * r * r / w;
            }
        }
    }
    f
}

/// Σ|F_i| [N].
pub fn total_force(f: &[Vector3<f64>]) -> f64 {
    f.iter().map(|v| v.norm()).sum()
}

/// Nodal loads of the bonded solve from forces [N] (no moments); `None` when all are zero.
pub fn as_nodal_loads(f: &[Vector3<f64>]) -> Option<Vec<NodalLoad>> {
    if f.iter().all(|v| *v == Vector3::zeros()) {
        return None;
    }
    Some(f.iter().map(|&force| NodalLoad { force, moment: Vector3::zeros() }).collect())
}

/// (P4): the macroscopic stress σ = (1/V) Σ_c f_c ⊗ l_c of the contact forces `forces` (force on A
/// by B [N]) with branch vectors l_c = x_B − x_A [m], over the volume `volume` [m³]; symmetric part
/// as `[xx, yy, zz, yz, xz, xy]` [Pa], tension positive (a compressive load gives σ_zz < 0).
pub fn macroscopic_stress(pairs: &[[u32; 2]], forces: &[Vector3<f64>], scale: f64, positions: &[Vector3<f64>], volume: f64) -> [f64; 6] {
    let mut s = nalgebra::Matrix3::<f64>::zeros();
    for (&[i, j], f) in pairs.iter().zip(forces) {
        let l = positions[j as usize] - positions[i as usize];
        s += (f * scale) * l.transpose();
    }
    let s = (s + s.transpose()) * (0.5 / volume);
    [s[(0, 0)], s[(1, 1)], s[(2, 2)], s[(1, 2)], s[(0, 2)], s[(0, 1)]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_interpolates_and_holds() {
        let p = StressProfile::from_table(&[[0.0, 0.0], [100.0, 1e7], [200.0, 1e7]]).unwrap();
        assert_eq!(p.at(-1.0), 0.0);
        assert_eq!(p.at(50.0), 5e6);
        assert_eq!(p.at(150.0), 1e7);
        assert_eq!(p.at(1e6), 1e7);
        assert!(StressProfile::from_table(&[[0.0, 0.0], [0.0, 1.0]]).is_err());
        let e = StressProfile::from_table(&[[0.0, -1.0]]).unwrap_err().to_string();
        assert!(e.contains("load.stress_table[0] stress") && e.contains("Pa"), "{e}");
    }

    #[test]
    fn face_forces_add_up_to_stress_times_area() {
        let ext = Vector3::new(2e-4, 3e-4, 5e-4);
        let radii = vec![1e-5, 2e-5, 1e-5, 1e-5];
        let far = [vec![0], vec![1], vec![2, 3]];
        let near = [vec![3], vec![2], vec![0, 1]];
        let f = nodal_forces(LoadMode::Uniaxial(2), 1e6, &ext, &radii, &far, &near, false);
        let fz: f64 = f.iter().map(|v| v.z).sum();
        assert!((fz + 1e6 * 2e-4 * 3e-4).abs() < 1e-15, "{fz}");
        assert_eq!(f[2], f[3]);
        let f = nodal_forces(LoadMode::Isostatic, 1e6, &ext, &radii, &far, &near, true);
        let sum: Vector3<f64> = f.iter().sum();
        assert!(sum.norm() < 1e-15);
    }
}
