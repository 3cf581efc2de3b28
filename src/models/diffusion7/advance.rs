//! Per-contact adaptive integration of the 7-DOF ODE over a global interval `[t0, t1]` with the
//! contact temperature varying inside it (docs/diffusion7.md §7; strategy 2's per-contact subdivision, docs/coupled.md (S3)):
//! substeps split exactly at the kinks of the temperature history and at the times it crosses a
//! phase-transition temperature (docs/diffusion7.md §3); each piece uses the phase of its midpoint temperature, and
//! RK stages evaluate T at their own times. Tolerance (T1): rtol relative to the state with a
//! floor `norm_floor·R_min`. Integration runs in the contact's own time `t − t_c` (docs/diffusion7.md §7).

use super::contact::Contact7;
use super::kinetics::rates_with;
use super::material::{ContactParams, Material, PathFactors};
use crate::error::ModelError;
use crate::models::ode::{Control, Method, OdeStats, integrate_while};
use crate::profile::Profile;
use serde::{Deserialize, Serialize};

/// Integrator settings of the 7-DOF contacts (case section `[solver]`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverOptions {
    /// `dopri5` (default), `rk4_doubling` or `rosenbrock4`.
    pub method: Method,
    /// Relative tolerance rtol (T1) [1].
    pub rtol: f64,
    /// Norm floor relative to the smaller initial radius (T1: 1e-4) [1].
    pub norm_floor: f64,
    /// Largest substep [s].
    pub max_substep: f64,
    /// ModelError when the proposed substep falls below this fraction of the contact age (docs/diffusion7.md §7: 1e-12) [1].
    pub min_step_rel: f64,
    /// ModelError after this many substeps in one call [1].
    pub max_substeps: f64,
    /// Compact runs: a contact whose change over a global step is bounded below the tolerance
    /// by (T2) (docs/diffusion7.md §7) keeps its state instead of being integrated (`true`,
    /// default); `false` integrates every contact every step.
    pub skip_unchanged: bool,
    /// Strategy-1 trial (not a case key): the first rejected step ends [`advance`] with the
    /// ModelError `ode::STEP_REJECTED` (docs/coupled.md (S1)).
    #[serde(skip)]
    pub stop_on_reject: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            method: Method::Dopri5,
            rtol: 1e-6,
            norm_floor: 1e-4,
            max_substep: 1e9,
            min_step_rel: 1e-12,
            max_substeps: 2e6,
            skip_unchanged: true,
            stop_on_reject: false,
        }
    }
}

impl SolverOptions {
    /// Checks the keys against the range table (`solver.*`).
    pub fn validate(&self) -> Result<(), crate::error::ConfigError> {
        let check = |k: &str, v: f64| crate::config::ranges::check_in(super::RANGES, k, v);
        check("solver.rtol", self.rtol)?;
        check("solver.norm_floor", self.norm_floor)?;
        check("solver.max_substep", self.max_substep)?;
        check("solver.min_step_rel", self.min_step_rel)?;
        check("solver.max_substeps", self.max_substeps)?;
        Ok(())
    }

    pub(crate) fn control(&self, r_min: f64) -> Control<7> {
        Control {
            method: self.method,
            rtol: self.rtol,
            floor: [self.norm_floor * r_min; 7],
            h_max: self.max_substep,
            min_step_rel: self.min_step_rel,
            max_substeps: self.max_substeps as u64,
            stop_on_reject: self.stop_on_reject,
        }
    }
}

/// The contact temperature over global time, piecewise linear between its kinks.
#[derive(Debug, Clone, Copy)]
pub enum TemperaturePath<'a> {
    /// Constant [K].
    Constant(f64),
    /// Linear from `temp0` [K] at `t0` [s] to `temp1` [K] at `t1` [s] (a global step, §3).
    Linear { t0: f64, temp0: f64, t1: f64, temp1: f64 },
    /// A heating profile (its breakpoints are the kinks).
    Profile(&'a Profile),
}

impl TemperaturePath<'_> {
    /// T(t) [K].
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        match *self {
            TemperaturePath::Constant(v) => v,
            TemperaturePath::Linear { t0, temp0, t1, temp1 } => {
                if t1 == t0 {
                    temp1
                } else {
                    temp0 + (temp1 - temp0) * (t - t0) / (t1 - t0)
                }
            }
            TemperaturePath::Profile(p) => p.temperature(t),
        }
    }

    /// Kinks strictly inside (t0, t1) [s].
    pub fn kinks(&self, t0: f64, t1: f64) -> Vec<f64> {
        match self {
            TemperaturePath::Profile(p) => p.split_points(t0, t1, None),
            _ => Vec::new(),
        }
    }
}

/// The two materials of a contact and the model factors.
#[derive(Debug, Clone, Copy)]
pub struct PairMaterials<'a> {
    pub a: &'a Material,
    pub b: &'a Material,
    pub factors: PathFactors,
}

impl PairMaterials<'_> {
    /// Parameters of the phase pair at contact temperature `t` [K] (§3).
    pub fn params_at(&self, t: f64) -> ContactParams {
        ContactParams::new(self.a, self.a.phase_at(t), self.b, self.b.phase_at(t), self.factors)
    }

    /// Phase-transition temperatures of either side [K].
    pub fn transitions(&self) -> Vec<f64> {
        let mut v: Vec<f64> = self.a.transitions().chain(self.b.transitions()).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    }
}

/// Times in `(t0, t1)` where the temperature has a kink or crosses a transition [s], sorted.
pub fn split_times(temp: &TemperaturePath, t0: f64, t1: f64, transitions: &[f64]) -> Vec<f64> {
    let mut pts = vec![t0];
    pts.extend(temp.kinks(t0, t1));
    pts.push(t1);
    let mut out = Vec::new();
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (ta, tb) = (temp.at(a), temp.at(b));
        for &tc in transitions {
            if (ta - tc) * (tb - tc) < 0.0 {
                let s = a + (tc - ta) / (tb - ta) * (b - a);
                if s > t0 && s < t1 {
                    out.push(s);
                }
            }
        }
        if b < t1 {
            out.push(b);
        }
    }
    out.sort_by(f64::total_cmp);
    out.dedup();
    out
}

/// Whether `split_times(temp, t0, t1, &mats.transitions())` is empty — no kink of the path and no
/// phase transition crossed inside `(t0, t1)` — without building the lists (the sweep asks this
/// of every contact in every step).
pub fn smooth_inside(temp: &TemperaturePath, mats: &PairMaterials, t0: f64, t1: f64) -> bool {
    if !temp.kinks(t0, t1).is_empty() {
        return false;
    }
    let (ta, tb) = (temp.at(t0), temp.at(t1));
    !mats.a.transitions().chain(mats.b.transitions()).any(|tc| {
        if (ta - tc) * (tb - tc) < 0.0 {
            let s = t0 + (tc - ta) / (tb - ta) * (t1 - t0);
            s > t0 && s < t1
        } else {
            false
        }
    })
}

/// Advances `contact` from global time `t0` to `t1` [s] (docs/coupled.md (S3), strategy 2: as many adaptive substeps as
/// needed). `on_step(t, y, T)` is called after every accepted substep with global time [s], state [m]
/// and contact temperature [K]. On error the contact is left unchanged.
pub fn advance<G>(
    contact: &mut Contact7,
    mats: &PairMaterials,
    temp: &TemperaturePath,
    t0: f64,
    t1: f64,
    opts: &SolverOptions,
    stats: &mut OdeStats,
    mut on_step: G,
) -> Result<(), ModelError>
where
    G: FnMut(f64, &[f64; 7], f64),
{
    let go_on = |t: f64, y: &[f64; 7], temp: f64| {
        on_step(t, y, temp);
        true
    };
    advance_while(contact, mats, temp, t0, t1, opts, stats, go_on).map(|_| ())
}

/// [`advance`] whose `on_step(t, y, T)` returns whether to go on: `false` ends the advance after
/// that accepted substep, with the contact at that state. Returns the global time it stopped at
/// [s], None when it reached `t1`.
pub fn advance_while<G>(
    contact: &mut Contact7,
    mats: &PairMaterials,
    temp: &TemperaturePath,
    t0: f64,
    t1: f64,
    opts: &SolverOptions,
    stats: &mut OdeStats,
    mut on_step: G,
) -> Result<Option<f64>, ModelError>
where
    G: FnMut(f64, &[f64; 7], f64) -> bool,
{
    let ctl = opts.control(contact.r_min());
    let tc = contact.t_created;
    let trans = mats.transitions();
    let mut pts = vec![t0];
    pts.extend(split_times(temp, t0, t1, &trans));
    pts.push(t1);
    let mut y = contact.y;
    let mut h = contact.h_last;
    // the contact's normal force (M11), constant over the interval (0: the unloaded model)
    let force = contact.normal_force;
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b <= a {
            continue;
        }
        let (ta, tb) = (temp.at(a), temp.at(b));
        let tmid = temp.at(0.5 * (a + b));
        let params = mats.params_at(tmid);
        let last = std::cell::Cell::new(y);
        let last_t = std::cell::Cell::new(a);
        let ctx = |e: ModelError| {
            // a collapse with the neck at the size of the smaller particle is its absorption (the
            // geometry, diagnosed below), not diffusion data too fast for the integrator
            let absorbed = {
                let y = last.get();
                y[0] >= 0.9 * y[1].min(y[4])
            };
            if e.message.starts_with(COLLAPSED) && !absorbed {
                let t = last_t.get();
                return ModelError::new(explain_collapse(mats, t, temp.at(t), &last.get()))
                    .with_context(format!("contact interval [{a:.6e}, {b:.6e}] s, T = {ta:.2} to {tb:.2} K; integrator: {}", e.message));
            }
            e.with_context(format!(
                "contact interval [{a:.6e}, {b:.6e}] s, T = {ta:.2} to {tb:.2} K; last accepted state: {}",
                super::contact::diagnose(&last.get())
            ))
        };
        let stopped_at = std::cell::Cell::new(None);
        let mut cb = |tau: f64, yy: &[f64; 7]| {
            let t = tau + tc;
            last.set(*yy);
            last_t.set(t);
            let go = on_step(t, yy, temp.at(t));
            if !go {
                stopped_at.set(Some(t));
            }
            go
        };
        let (ynew, _) = if ta == tb {
            let mut k = params.at(ta).map_err(ctx)?;
            k.normal_force = force;
            let mut f = |_tau: f64, yy: &[f64; 7]| rates_with(yy, &k);
            integrate_while(&mut f, a - tc, b - tc, y, &mut h, &ctl, stats, &mut cb).map_err(ctx)?
        } else {
            let mut f = |tau: f64, yy: &[f64; 7]| {
                let mut k = params.at(temp.at(tau + tc))?;
                k.normal_force = force;
                rates_with(yy, &k)
            };
            integrate_while(&mut f, a - tc, b - tc, y, &mut h, &ctl, stats, &mut cb).map_err(ctx)?
        };
        y = ynew;
        if let Some(t) = stopped_at.get() {
            contact.y = y;
            contact.h_last = h;
            return Ok(Some(t));
        }
    }
    contact.y = y;
    contact.h_last = h;
    Ok(None)
}

/// The start of the integrator's message when its substep collapses (`crate::models::ode`).
const COLLAPSED: &str = "step size collapsed";

/// Fastest believable diffusion coefficient of a solid [m²/s]: surface diffusion near the melting
/// point reaches about 1e-8 m²/s, diffusion in liquid metals about 1e-9 m²/s.
pub const D_IMPLAUSIBLE: f64 = 1e-7;

/// The cause of a collapsed substep in physical terms (issue 25): the contact's neck grew faster
/// than the integrator can follow, and the diffusion data that make it so fast — the mechanism with
/// an activation energy typical of kJ/mol or a coefficient above [`D_IMPLAUSIBLE`] first, else the
/// fastest one (transport measure δ·D for surface and grain boundary, D·R_min for the lattice,
/// docs/diffusion7.md (M4)), with D0, Q and D(T) (M9).
pub fn explain_collapse(mats: &PairMaterials, t: f64, temp: f64, y: &[f64; 7]) -> String {
    let r_min = y[1].min(y[4]);
    // (suspicion, measure, text)
    let mut cands: Vec<(bool, f64, String)> = Vec::new();
    for m in [mats.a, mats.b] {
        let ph = &m.phases[m.phase_at(temp)];
        for (mech, key, d0, q, layer) in [
            ("surface diffusion", "surface", ph.d0_surface, ph.q_surface, ph.delta_surface * ph.mobile_fraction_surface),
            ("grain-boundary diffusion", "gb", ph.d0_gb, ph.q_gb, ph.delta_gb * ph.mobile_fraction_gb),
            ("lattice diffusion", "lattice", ph.d0_lattice, ph.q_lattice, ph.mobile_fraction_lattice * r_min),
        ] {
            let d = super::material::Arrhenius { d0, q }.at(temp);
            let hint = if q > 0.0 && q < 1e4 {
                format!(" (q_{key} = {q} J/mol looks like kJ/mol: Q is in J/mol)")
            } else if d > D_IMPLAUSIBLE {
                format!(" (faster than diffusion in a liquid metal, about 1e-9 m²/s: d0_{key} or q_{key} is likely wrong)")
            } else {
                String::new()
            };
            let text = format!(
                "{mech} of material \"{}\" (phase \"{}\"): D = {d:.3e} m²/s at {temp:.1} K from d0_{key} = {d0:e} m²/s, q_{key} = {q:e} J/mol{hint}",
                m.name, ph.name
            );
            if !cands.iter().any(|c| c.2 == text) {
                cands.push((!hint.is_empty(), layer * d, text));
            }
        }
    }
    cands.sort_by(|x, y| y.0.cmp(&x.0).then(y.1.total_cmp(&x.1)));
    let names: Vec<&str> = {
        let mut v = vec![mats.a.name.as_str()];
        if mats.b.name != mats.a.name {
            v.push(mats.b.name.as_str());
        }
        v
    };
    let top = cands.first().map(|c| c.2.clone()).unwrap_or_default();
    // plausible data and a neck at the end of the two-cap geometry (docs/diffusion7.md "Validity
    // limits": a cone tangent to its cap, copper at y1/R ≈ 0.73): the model's limit, not the data
    // (issue 39: the library's alumina at 1673 K, R = 0.5 µm, stopped at y1/R = 0.697)
    let theta = super::contact::tangency(y).map(|t| t[0].max(t[1])).unwrap_or(1.0);
    if !cands.first().is_some_and(|c| c.0) && (theta > 0.9 || y[0] / r_min >= 0.65) {
        return format!(
            "the contact reached the end of the model's two-cap geometry at t = {t:.4e} s (T = {temp:.1} K): {}. This is the validity limit of the 7-DOF model (docs/diffusion7.md \"Validity limits\"), not a data problem: the fastest transport, {top}, is plausible. The rows up to here are valid; a shorter end time (or a lower temperature) stays inside the model",
            super::contact::diagnose(y)
        );
    }
    format!(
        "the contact's neck growth outran the integrator at t = {t:.4e} s (T = {temp:.1} K, neck y1/R_min = {:.3}): the diffusion is too fast for the geometry. The {} is {top}; check the diffusion data of material {}",
        y[0] / r_min,
        if cands.first().is_some_and(|c| c.0) { "suspect" } else { "fastest transport" },
        names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(" and ")
    )
}

/// A warning if `[t_lo, t_hi]` [K] leaves the calibrated range of `m` (docs/diffusion7.md §10).
pub fn calibrated_range_warning(m: &Material, t_lo: f64, t_hi: f64) -> Option<String> {
    if t_lo < m.calibrated_min_temperature || t_hi > m.calibrated_max_temperature {
        Some(format!(
            "contact temperature {:.1}–{:.1} K leaves the calibrated range {:.1}–{:.1} K of material \"{}\": its diffusion data are extrapolated",
            t_lo, t_hi, m.calibrated_min_temperature, m.calibrated_max_temperature, m.name
        ))
    } else {
        None
    }
}
