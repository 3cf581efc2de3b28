//! The branch runs of one density point (docs/rve.md (R1)–(R8)): clones of the free run's state
//! (its checkpoint, so each clone continues exactly as a resumed run would), advanced over the same
//! fixed steps free and under compressive stress perturbations of the cell; the constitutive
//! quantities from the differences of their strain rates.

use super::RveSettings;
use crate::coupled::Simulation;
use crate::coupled::cell::Control;
use crate::error::{Error, ModelError};
use crate::kinds::compact::OutputState;

/// One row of `constitutive.csv` (docs/rve.md "Output"); stresses tension positive, strain rates
/// d ln L/dt (negative while shrinking).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Point {
    /// Time of the free run [s], mean particle temperature [K].
    pub time: f64,
    pub temperature: f64,
    /// Relative density (B22) [1], mean linear shrinkage of the cell [1], mean neck ratio y1/R [1].
    pub relative_density: f64,
    pub shrinkage: f64,
    pub neck_ratio: f64,
    /// Free volumetric strain rate ε̇_v = Σ_a ε̇_aa of the free branch (R2) [1/s].
    pub volumetric_rate_free: f64,
    /// Perturbation Δ (R1) [Pa] (its magnitude; the applied stresses are −Δ).
    pub perturbation: f64,
    /// (R3) bulk viscosity K [Pa·s] at Δ and at Δ/2.
    pub bulk_viscosity: f64,
    pub bulk_viscosity_half: f64,
    /// (R4) uniaxial viscosity E_p [Pa·s], mean over the three axes; along x at Δ and Δ/2; the
    /// spread (standard deviation over the axes / mean) [1].
    pub uniaxial_viscosity: f64,
    pub uniaxial_viscosity_x: f64,
    pub uniaxial_viscosity_x_half: f64,
    pub uniaxial_spread: f64,
    /// (R5) viscous Poisson ratio ν_p [1], mean over the axes.
    pub poisson_ratio: f64,
    /// (R6) shear viscosity G [Pa·s].
    pub shear_viscosity: f64,
    /// (R8) the Poisson ratio an isotropic linear viscous body with this K and E_p would have,
    /// (3K − E_p)/(6K) [1]: against [`Point::poisson_ratio`], how far the cell is from it.
    pub poisson_ratio_isotropic: f64,
    /// (R7) sintering stress σ_s = −K·ε̇_v,free [Pa] (tensile positive), and the cell's (B23)
    /// measure at the branch point (mean of the normal components) [Pa].
    pub sintering_stress: f64,
    pub sintering_stress_b23: f64,
    /// Effective conductivity tensor [W/(m·K)] `[xx, yy, zz, yz, xz, xy]` (periodic homogenisation).
    pub kappa: [f64; 6],
    /// Mean h/r of the contacts [1] and whether it lies beyond the FE-validated range of the
    /// conductance law (`heat::conductance::VALIDATED_MEAN_OVERLAP_RATIO`): κ then extrapolated.
    pub mean_overlap_over_radius: f64,
    pub kappa_extrapolated: bool,
}

/// A clone of `sim` (its checkpoint state rebuilt, as `sinterdem resume` does) with every normal
/// component of the cell held at the stress `stress` [Pa] from now on and `steps` equal global
/// steps of `interval / steps` [s] to run; returns the cell's log-strains after each step.
fn branch(sim: &Simulation, stress: [f64; 3], interval: f64, steps: u32) -> Result<Vec<[f64; 3]>, Error> {
    let (mut b, _) = Simulation::from_checkpoint(&sim.checkpoint(OutputState { series_lines: 1, ..OutputState::default() }), &mut |_| {})?;
    if let Some(cs) = b.settings.mechanics.cell.as_mut() {
        for (k, s) in stress.iter().enumerate() {
            cs.controls[k] = Control::Stress(vec![[0.0, *s]]);
        }
    }
    let h = interval / steps as f64;
    let t0 = b.t;
    b.settings.end = t0 + interval;
    b.settings.dt_max = h;
    b.dt = h;
    let strain = |b: &Simulation| -> [f64; 3] {
        let l = b.cell.as_ref().map(|c| c.lengths()).unwrap_or_default();
        [l.x.ln(), l.y.ln(), l.z.ln()]
    };
    let mut out = vec![strain(&b)];
    let mut guard = 0;
    while b.t < b.settings.end * (1.0 - 1e-14) {
        b.stop_at = t0 + h * out.len() as f64;
        b.advance_step(&mut |_| {})?;
        guard += 1;
        if guard > 100 * steps as usize {
            return Err(ModelError::new(format!("rve branch from t = {t0} s: more than {} steps for {steps} planned", 100 * steps)).into());
        }
        // a step shortened by the step control is followed by the rest of the planned step
        if b.t >= b.stop_at * (1.0 - 1e-12) {
            out.push(strain(&b));
        }
        b.dt = h;
    }
    if out.len() < steps as usize + 1 {
        return Err(ModelError::new(format!(
            "rve branch from t = {t0} s: {} of {steps} planned steps of {h:e} s taken (the step is below the time resolution)",
            out.len() - 1
        ))
        .into());
    }
    Ok(out)
}

/// The strain rates [1/s] of a branch over its planned steps 2..n (R2): the first step carries
/// the elastic jump of the stress change, the rest is viscous.
fn rates(strains: &[[f64; 3]], interval: f64, steps: u32) -> [f64; 3] {
    let h = interval / steps as f64;
    let (a, b) = (strains[1], strains[strains.len() - 1]);
    let span = h * (strains.len() - 2) as f64;
    [(b[0] - a[0]) / span, (b[1] - a[1]) / span, (b[2] - a[2]) / span]
}

/// The constitutive quantities at the current state of the free run `sim` (docs/rve.md (R1)–(R8)):
/// seven branches (free; hydrostatic −Δ and −Δ/2; uniaxial −Δ along x, y, z; uniaxial −Δ/2 along
/// x), Δ = `rve.perturbation` times the (B23) mean sintering stress.
pub fn measure_point(sim: &Simulation, rve: &RveSettings) -> Result<Point, Error> {
    let b23 =
        sim.sintering_stress()?.ok_or_else(|| crate::error::ConfigError::invalid("sinterdem rve needs a periodic cell (mechanics.boundary = \"periodic\")"))?;
    let b23_mean = (b23[0] + b23[1] + b23[2]) / 3.0;
    if !(b23_mean.is_finite() && b23_mean > 0.0) {
        return Err(ModelError::new(format!(
            "rve point at t = {} s: the (B23) sintering stress is {b23_mean:e} Pa (not positive): no driving force to perturb (are the necks there yet?)",
            sim.t
        ))
        .into());
    }
    let d = rve.perturbation * b23_mean;
    let (tau, n) = (rve.interval, rve.steps);
    let run = |s: [f64; 3]| -> Result<[f64; 3], Error> { Ok(rates(&branch(sim, s, tau, n)?, tau, n)) };
    let free = run([0.0; 3])?;
    let diff = |r: [f64; 3]| [r[0] - free[0], r[1] - free[1], r[2] - free[2]];
    let vol = |r: [f64; 3]| r[0] + r[1] + r[2];
    // (R3) K = Δσ_m / Δε̇_v with Δσ_m = −Δ
    let hyd = diff(run([-d; 3])?);
    let hyd_half = diff(run([-0.5 * d; 3])?);
    let bulk = -d / vol(hyd);
    let bulk_half = -0.5 * d / vol(hyd_half);
    // (R4), (R5) along each axis
    let mut e_axes = [0.0; 3];
    let mut nu_axes = [0.0; 3];
    for a in 0..3 {
        let mut s = [0.0; 3];
        s[a] = -d;
        let r = diff(run(s)?);
        e_axes[a] = -d / r[a];
        let lat: f64 = (0..3).filter(|&b| b != a).map(|b| r[b]).sum::<f64>() / 2.0;
        nu_axes[a] = -lat / r[a];
    }
    let mut s = [0.0; 3];
    s[0] = -0.5 * d;
    let r = diff(run(s)?);
    let e_x_half = -0.5 * d / r[0];
    let e_mean = e_axes.iter().sum::<f64>() / 3.0;
    let e_spread = (e_axes.iter().map(|e| (e - e_mean) * (e - e_mean)).sum::<f64>() / 3.0).sqrt() / e_mean;
    let nu = nu_axes.iter().sum::<f64>() / 3.0;
    let ev_free = vol(free);
    let kappa = match crate::kinds::compact::periodic_conductivity(sim)? {
        Some(k) => [k[(0, 0)], k[(1, 1)], k[(2, 2)], k[(1, 2)], k[(0, 2)], k[(0, 1)]],
        None => [0.0; 6],
    };
    let sh = sim.shrinkage();
    let hr = crate::kinds::compact::mean_overlap_ratio(sim);
    let temps = &sim.prep.scene.particles.temperature;
    let point = Point {
        time: sim.t,
        temperature: temps.iter().sum::<f64>() / temps.len().max(1) as f64,
        relative_density: sim.relative_density(),
        shrinkage: (sh.x + sh.y + sh.z) / 3.0,
        neck_ratio: sim.mean_neck_ratio(),
        volumetric_rate_free: ev_free,
        perturbation: d,
        bulk_viscosity: bulk,
        bulk_viscosity_half: bulk_half,
        uniaxial_viscosity: e_mean,
        uniaxial_viscosity_x: e_axes[0],
        uniaxial_viscosity_x_half: e_x_half,
        uniaxial_spread: e_spread,
        poisson_ratio: nu,
        shear_viscosity: shear_viscosity(bulk, e_mean),
        poisson_ratio_isotropic: (3.0 * bulk - e_mean) / (6.0 * bulk),
        sintering_stress: -bulk * ev_free,
        sintering_stress_b23: b23_mean,
        kappa,
        mean_overlap_over_radius: hr,
        kappa_extrapolated: crate::heat::conductance::beyond_validated(hr),
    };
    let values = [point.bulk_viscosity, point.bulk_viscosity_half, point.uniaxial_viscosity, point.uniaxial_viscosity_x_half, point.sintering_stress];
    if values.iter().any(|v| !v.is_finite()) {
        // a zero strain-rate difference: the perturbed branches crept exactly as the free one to
        // the last bit of the cell's log-strain (issue 38: copper at 300 K gave K = -inf)
        return Err(ModelError::new(format!(
            "rve point at t = {} s (mean temperature {:.1} K): the branches under the stress perturbation Δ = {:.3e} Pa did not creep measurably in rve.interval = {} s \
             (volumetric strain-rate difference {:e} 1/s, uniaxial {:e} 1/s: zero to the resolution of the cell's strain), so the viscosities are beyond what \
             this interval resolves: at this temperature the necks hardly diffuse. Measure where the cell sinters (a higher temperature), or over a longer rve.interval",
            crate::error::fmt_value(sim.t),
            point.temperature,
            d,
            crate::error::fmt_value(tau),
            vol(hyd),
            e_axes.iter().map(|e| -d / e).fold(0.0, |a: f64, b| if b.abs() > a.abs() { b } else { a }),
        ))
        .with_context(format!("step {}, t = {} s", sim.step, crate::error::fmt_value(sim.t)))
        .into());
    }
    crate::finite::ensure_finite("rve branches", sim.step, sim.t, "quantity", "constitutive value", values.iter().copied())?;
    Ok(point)
}

/// (R6) the shear viscosity of an isotropic linear viscous body from its bulk viscosity K and
/// uniaxial viscosity E_p [Pa·s]: G = 3K·E_p / (9K − E_p).
pub fn shear_viscosity(bulk: f64, uniaxial: f64) -> f64 {
    3.0 * bulk * uniaxial / (9.0 * bulk - uniaxial)
}
