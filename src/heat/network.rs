//! The implicit pipe-network heat solve (docs/heat-model.md (H1)–(H5)).
//!
//! Per free particle i (Dirichlet particles follow their heating profile):
//! `C_i dT_i/dt = f_i(T, t) = Σ_j K_ij (T_j − T_i) + h_c A_i (T_gas − T_i) + εσA_i (T_wall⁴ − T_i⁴) + Q_i`.
//! Every scheme is written as `M_i T_i^{n+1} − w f_i(T^{n+1}, t^{n+1}) = r_i`:
//! - backward Euler: `M = C/Δt`, `w = 1`, `r = C/Δt T^n`;
//! - Crank–Nicolson: `M = C/Δt`, `w = ½`, `r = C/Δt T^n + ½ f(T^n, t^n)`;
//! - BDF2 (variable step, ω = Δt_n/Δt_{n−1}): `M = a0 C/Δt`, `w = 1`, `r = −C (a1 T^n + a2 T^{n−1})/Δt`,
//!   `a0 = (1+2ω)/(1+ω)`, `a1 = −(1+ω)`, `a2 = ω²/(1+ω)`; its first step is backward Euler.
//!
//! Radiation is linearised about the iterate T* (diagonal `+4εσA T*³`, right-hand side
//! `+εσA (T_wall⁴ + 3T*⁴)`) and iterated until `max|ΔT| ≤ tol·max T` (at most 20 iterations).
//! The matrix `M + w(L + diag)` is SPD for any network; its factor is reused while the values are
//! unchanged (fixed network, constant Δt, no radiation).
//!
//! Energy: each step reports the heat that entered the free particles through Dirichlet pipes,
//! convection, radiation and volumetric sources, `Δt [w g(T^{n+1}) + (1−w) g(T^n)]`, and the
//! scheme's stored-heat change `Σ C (a0 T^{n+1} + a1 T^n + a2 T^{n−1})` (`Σ C ΔT` for one-step
//! schemes); their difference is the discrete energy-balance residual (round-off).

use crate::error::SolveError;
use crate::heat::PipeConductance;
use crate::heat::properties::ThermalProperties;
use crate::linsolve::{SolveInfo, SpdFactor, SpdPattern, set_parallelism_for};
use crate::material::Table;
use crate::profile::Profile;
use crate::units::STEFAN_BOLTZMANN;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Time integration scheme of the heat network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// First order, L-stable.
    BackwardEuler,
    /// Second order, A-stable (not L-stable: stiff modes oscillate at large Δt).
    CrankNicolson,
    /// Second order, L-stable-like damping; variable step.
    #[default]
    Bdf2,
}

impl Scheme {
    /// Global order of accuracy.
    pub fn order(self) -> u32 {
        match self {
            Scheme::BackwardEuler => 1,
            _ => 2,
        }
    }
}

/// Furnace atmosphere exchanging heat with exposed particles.
#[derive(Debug, Clone)]
pub struct Furnace {
    /// Gas temperature for convection [K].
    pub gas: Profile,
    /// Wall temperature for radiation [K].
    pub wall: Profile,
    /// Convective coefficient h_c [W/(m²·K)].
    pub convection: f64,
    /// Emissivity ε [1].
    pub emissivity: f64,
}

/// Everything about the heat problem that does not change with the contact topology.
#[derive(Debug, Clone, Default)]
pub struct HeatSources {
    /// For each particle: index into `profiles` if its temperature is prescribed, else `None`.
    pub fixed: Vec<Option<u32>>,
    /// Heating profiles of the Dirichlet regions.
    pub profiles: Vec<Profile>,
    /// Exposed area A_i^exp per particle [m²] (0: not exposed).
    pub exposed_area: Vec<f64>,
    /// Volumetric heat generation per particle, Q_i = q‴ V_i [W].
    pub power: Vec<f64>,
    /// The furnace, if any particle is exposed.
    pub furnace: Option<Furnace>,
}

/// Per-step report.
#[derive(Debug, Clone, Copy, Default)]
pub struct HeatStepInfo {
    /// Heat into the free particles over the step [J].
    pub heat_in: f64,
    /// Scheme's stored-heat change over the step [J].
    pub stored_change: f64,
    /// Plain Σ C_i (T_i^{n+1} − T_i^n) over free particles [J].
    pub stored_change_plain: f64,
    /// Radiation Newton iterations (1 without radiation).
    pub iterations: u32,
    /// Whether the factor of the previous step was reused.
    pub reused_factor: bool,
    /// Assembly wall time [s].
    pub assemble_seconds: f64,
    /// Last solve's report.
    pub solve: SolveInfo,
    /// Symbolic analysis wall time spent in this step (topology change) [s].
    pub symbolic_seconds: f64,
}

/// Local error estimate for adaptive stepping is not part of this struct: the scheme's order is
/// verified by the convergence tests; see docs/heat-model.md.
pub struct HeatNetwork {
    capacity: Vec<f64>,
    sources: HeatSources,
    scheme: Scheme,
    radiation_tol: f64,
    // topology
    pipes: Vec<[u32; 2]>,
    free: Vec<u32>,
    local: Vec<u32>,
    pipe_entry: Vec<u32>,
    pattern: Option<SpdPattern>,
    factor: Option<SpdFactor>,
    // history for BDF2
    prev: Option<(Vec<f64>, f64)>,
    // temperature-dependent properties (heat-model.md eqs. P1–P4)
    props: Option<ThermalProperties>,
    // pipes [0, contact_pipes) are contacts (rescaled by κ(T), in series with K_c); the rest are
    // gap pipes (heat-model.md (H18)–(H23)) with their radiation coefficients c [W/K⁴] (empty:
    // none radiates)
    contact_pipes: usize,
    gap_radiation: Vec<f64>,
}

const NONE: u32 = u32::MAX;

impl HeatNetwork {
    /// The values of the matrix factored last (None before the first solve): a checkpoint keeps
    /// their fingerprint, so that a resumed run counts its rebuild of the same factor as the
    /// uninterrupted run's reuse (issue 38: `factorizations` 3 against 2).
    pub fn factored_values(&self) -> Option<&[f64]> {
        self.factor.as_ref().map(|f| f.values.as_slice())
    }

    /// `capacity`: C_i = m_i c [J/K] per particle.
    pub fn new(capacity: Vec<f64>, sources: HeatSources, scheme: Scheme, radiation_tol: f64) -> Self {
        let n = capacity.len();
        let mut s = sources;
        s.fixed.resize(n, None);
        s.exposed_area.resize(n, 0.0);
        s.power.resize(n, 0.0);
        let free: Vec<u32> = (0..n as u32).filter(|&i| s.fixed[i as usize].is_none()).collect();
        let mut local = vec![NONE; n];
        for (k, &i) in free.iter().enumerate() {
            local[i as usize] = k as u32;
        }
        HeatNetwork {
            capacity,
            sources: s,
            scheme,
            radiation_tol,
            pipes: Vec::new(),
            free,
            local,
            pipe_entry: Vec::new(),
            pattern: None,
            factor: None,
            prev: None,
            props: None,
            contact_pipes: 0,
            gap_radiation: Vec::new(),
        }
    }

    /// Sets temperature-dependent properties (`None`: the constant capacities and conductances).
    /// With c(T) the steps solve the enthalpy form (eqs. P1–P2), with κ(T) they need
    /// [`step_pipes`](Self::step_pipes); both iterate (Picard) to `radiation_tol`.
    pub fn set_properties(&mut self, props: Option<ThermalProperties>) {
        self.props = props;
    }

    /// The temperature-dependent properties, if any.
    pub fn properties(&self) -> Option<&ThermalProperties> {
        self.props.as_ref()
    }

    /// H_i(b) − H_i(a) of particle `i` [J]: `C_i (b − a)` with a constant capacity, `m_i ∫_a^b c dT`
    /// with a table (eq. P1).
    pub fn enthalpy_change(&self, i: usize, a: f64, b: f64) -> f64 {
        match self.props.as_ref().and_then(|p| p.capacity_table(i).map(|t| (t, p.mass[i]))) {
            Some((t, m)) => m * t.integral(a, b),
            None => self.capacity[i] * (b - a),
        }
    }

    /// Stored heat of the free particles, Σ H_i(T_i) with H_i(T) = C_i T (constant capacity) or
    /// `m_i ∫_0^T c dT` (eq. P1) [J].
    pub fn stored_heat(&self, temps: &[f64]) -> f64 {
        self.free.iter().map(|&i| self.enthalpy_change(i as usize, 0.0, temps[i as usize])).sum()
    }

    /// dT_i/dt [K/s] per particle at (`temps`, `t`) (0 for Dirichlet particles): `f_i / C_i(T_i)`.
    pub fn rate_of_change(&self, t: f64, temps: &[f64], pipes: &[PipeConductance]) -> Vec<f64> {
        let k = self.conductances_at(temps, pipes);
        let mut f = vec![0.0; self.free.len()];
        self.rates(temps, t, &k, &mut f);
        let mut out = vec![0.0; temps.len()];
        for (l, &i) in self.free.iter().enumerate() {
            let i = i as usize;
            let c = match self.props.as_ref().and_then(|p| p.capacity_table(i).map(|t| (t, p.mass[i]))) {
                Some((t, m)) => m * t.at(temps[i]),
                None => self.capacity[i],
            };
            out[i] = f[l] / c;
        }
        out
    }

    /// Pipe conductances [W/K] at `temps`: the pairs' values, or with κ(T) eq. P4; gap pipes add
    /// their radiation (H23).
    fn conductances_at(&self, temps: &[f64], pipes: &[PipeConductance]) -> Vec<f64> {
        let k: Vec<f64> = pipes.iter().map(|p| p.pair).collect();
        let halves = self.props.as_ref().is_some_and(|p| p.has_conductivity()).then_some(pipes);
        pipe_values(&self.pipes, self.contact_pipes, self.props.as_ref(), &self.gap_radiation, temps, &k, halves)
    }

    pub fn scheme(&self) -> Scheme {
        self.scheme
    }

    pub fn sources(&self) -> &HeatSources {
        &self.sources
    }

    /// Replaces the furnace's temperature histories (a caller holding the furnace at a new
    /// temperature between steps); the exposed particles stay those of the case.
    pub fn set_furnace(&mut self, furnace: Furnace) {
        self.sources.furnace = Some(furnace);
    }

    /// Number of unknowns (free particles).
    pub fn unknowns(&self) -> usize {
        self.free.len()
    }

    /// Whether particle `i` follows a prescribed profile.
    pub fn is_fixed(&self, i: usize) -> bool {
        self.sources.fixed[i].is_some()
    }

    fn has_radiation(&self) -> bool {
        self.sources.furnace.as_ref().is_some_and(|f| f.emissivity > 0.0) && self.sources.exposed_area.iter().any(|&a| a > 0.0)
    }

    /// Sets the pipes `(i, j)`; the sparsity pattern and symbolic factorisation are rebuilt only
    /// when the list differs from the current one.
    pub fn set_topology(&mut self, pipes: &[[u32; 2]]) -> Result<f64, SolveError> {
        self.set_topology_with_gaps(pipes, &[])
    }

    /// Sets the contact pipes `contacts` followed by the gap pipes `gaps` (heat-model.md
    /// (H18)–(H23)): the conductances passed to a step then list the contacts first. Gap pipes
    /// carry the gas conductance as given (κ(T) tables and K_c act on contact pipes only) plus
    /// their radiation ([`set_gap_radiation`](Self::set_gap_radiation)). The pattern is rebuilt
    /// only when a list differs from the current one; a rebuild forgets the radiation coefficients.
    pub fn set_topology_with_gaps(&mut self, contacts: &[[u32; 2]], gaps: &[[u32; 2]]) -> Result<f64, SolveError> {
        let nc = contacts.len();
        if self.pattern.is_some()
            && nc == self.contact_pipes
            && self.pipes.len() == nc + gaps.len()
            && contacts == &self.pipes[..nc]
            && gaps == &self.pipes[nc..]
        {
            return Ok(0.0);
        }
        let mut pipes = contacts.to_vec();
        pipes.extend_from_slice(gaps);
        let pipes = pipes.as_slice();
        self.contact_pipes = nc;
        self.gap_radiation.clear();
        self.pipes = pipes.to_vec();
        let nf = self.free.len();
        let mut entries: Vec<(u32, u32)> = (0..nf as u32).map(|k| (k, k)).collect();
        self.pipe_entry = vec![NONE; pipes.len()];
        for (p, &[i, j]) in pipes.iter().enumerate() {
            let (li, lj) = (self.local[i as usize], self.local[j as usize]);
            if li != NONE && lj != NONE && li != lj {
                self.pipe_entry[p] = entries.len() as u32;
                entries.push((li.max(lj), li.min(lj)));
            }
        }
        set_parallelism_for(nf);
        let pat = SpdPattern::new(nf, &entries)?;
        let secs = pat.symbolic_seconds;
        self.pattern = Some(pat);
        self.factor = None;
        Ok(secs)
    }

    /// Sets the radiation coefficients c [W/K⁴] of the gap pipes (H22), one per gap pipe of
    /// [`set_topology_with_gaps`](Self::set_topology_with_gaps); all zero (or empty) turns the
    /// radiation off. With radiation every step iterates (Picard) on the exact secant conductance
    /// `c (T_i² + T_j²)(T_i + T_j)` (H23) to `radiation_tolerance`.
    pub fn set_gap_radiation(&mut self, coefficients: &[f64]) -> Result<(), SolveError> {
        let n_gap = self.pipes.len() - self.contact_pipes;
        if coefficients.iter().all(|&c| c == 0.0) {
            self.gap_radiation.clear();
            return Ok(());
        }
        if coefficients.len() != n_gap || coefficients.iter().any(|c| !(c.is_finite() && *c >= 0.0)) {
            return Err(SolveError::new("heat gap radiation", format!("{} coefficients for {n_gap} gap pipes (each finite and ≥ 0 W/K⁴)", coefficients.len())));
        }
        self.gap_radiation = coefficients.to_vec();
        Ok(())
    }

    /// Number of gap pipes of the topology (heat-model.md (H18)).
    pub fn gap_pipes(&self) -> usize {
        self.pipes.len() - self.contact_pipes
    }

    /// Sets Dirichlet particles to their profile at time `t` [s].
    pub fn apply_fixed(&self, t: f64, temps: &mut [f64]) {
        for (i, f) in self.sources.fixed.iter().enumerate() {
            if let Some(p) = f {
                temps[i] = self.sources.profiles[*p as usize].temperature(t);
            }
        }
    }

    /// f_i(T, t) for every free particle (local order), and g = the heat into the free set [W].
    fn rates(&self, temps: &[f64], t: f64, conductance: &[f64], out: &mut [f64]) -> f64 {
        out.iter_mut().for_each(|v| *v = 0.0);
        let mut g = 0.0;
        for (p, &[i, j]) in self.pipes.iter().enumerate() {
            let k = conductance[p];
            let (li, lj) = (self.local[i as usize], self.local[j as usize]);
            let q = k * (temps[j as usize] - temps[i as usize]); // into i
            if li != NONE {
                out[li as usize] += q;
                if lj == NONE {
                    g += q;
                }
            }
            if lj != NONE {
                out[lj as usize] -= q;
                if li == NONE {
                    g -= q;
                }
            }
        }
        let (tg, tw4, hc, eps) = self.furnace_at(t);
        for (l, &i) in self.free.iter().enumerate() {
            let i = i as usize;
            let ti = temps[i];
            let a = self.sources.exposed_area[i];
            let ext = hc * a * (tg - ti) + eps * STEFAN_BOLTZMANN * a * (tw4 - ti.powi(4)) + self.sources.power[i];
            out[l] += ext;
            g += ext;
        }
        g
    }

    fn furnace_at(&self, t: f64) -> (f64, f64, f64, f64) {
        match &self.sources.furnace {
            Some(f) => (f.gas.temperature(t), f.wall.temperature(t).powi(4), f.convection, f.emissivity),
            None => (0.0, 0.0, 0.0, 0.0),
        }
    }

    /// The BDF2 history (T^{n−1} [K], Δt_{n−1} [s]) for checkpoints.
    pub fn history(&self) -> Option<&(Vec<f64>, f64)> {
        self.prev.as_ref()
    }

    /// Restores the BDF2 history from a checkpoint.
    pub fn set_history(&mut self, h: Option<(Vec<f64>, f64)>) {
        self.prev = h;
    }

    /// Forgets the BDF2 history (after a rejected step or a topology change, the next step is
    /// backward Euler).
    pub fn reset_history(&mut self) {
        self.prev = None;
    }

    /// Advances `temps` [K] from `t` to `t + dt` [s] with pipe conductances `conductance` [W/K]
    /// (one per pipe of [`set_topology`](Self::set_topology)). A network with κ(T) needs
    /// [`step_pipes`](Self::step_pipes).
    pub fn step(&mut self, t: f64, dt: f64, temps: &mut [f64], conductance: &[f64]) -> Result<HeatStepInfo, SolveError> {
        if self.props.as_ref().is_some_and(|p| p.has_conductivity()) {
            return Err(SolveError::new("heat step", "a network with temperature-dependent conductivity needs the pipe halves (step_pipes)"));
        }
        self.step_impl(t, dt, temps, conductance, None)
    }

    /// [`step`](Self::step) with the pipes' halves and series conductance computed with the
    /// materials' constant κ (κ_ref); with κ(T) the halves are rescaled by eq. P3.
    pub fn step_pipes(&mut self, t: f64, dt: f64, temps: &mut [f64], pipes: &[PipeConductance]) -> Result<HeatStepInfo, SolveError> {
        let k: Vec<f64> = pipes.iter().map(|p| p.pair).collect();
        let kappa = self.props.as_ref().is_some_and(|p| p.has_conductivity());
        self.step_impl(t, dt, temps, &k, kappa.then_some(pipes))
    }

    fn step_impl(&mut self, t: f64, dt: f64, temps: &mut [f64], conductance: &[f64], halves: Option<&[PipeConductance]>) -> Result<HeatStepInfo, SolveError> {
        self.check_step(dt, conductance, halves)?;
        let Some(pattern) = self.pattern.as_ref() else {
            return Err(SolveError::new("heat step", "set_topology was not called"));
        };
        let t1 = t + dt;
        let t_old: Vec<f64> = temps.to_vec();
        let co = self.coefficients(dt, temps.len());
        let (rhs0, g_old) = self.explicit_part(&co, t, dt, &t_old, conductance, halves);
        self.apply_fixed(t1, temps);
        let sys = StepSystem { co, dt, t_old: &t_old, rhs0, furnace: self.furnace_at(t1), conductance, halves };
        // the factor is updated in place by the iteration (kept also when a later stage fails)
        let mut factor = self.factor.take();
        let iterated = self.iterate(&sys, pattern, &mut factor, temps);
        self.factor = factor;
        let (x, k_last, mut info) = iterated?;
        for (l, &i) in self.free.iter().enumerate() {
            temps[i as usize] = x[l];
        }
        if let Some(k) = temps.iter().position(|v| !v.is_finite() || *v <= 0.0) {
            return Err(SolveError::new("heat step", format!("particle {k} reached a non-physical temperature {} K", temps[k])));
        }
        (info.heat_in, info.stored_change, info.stored_change_plain) = self.energy(&sys, t1, temps, &k_last, g_old);
        if self.scheme == Scheme::Bdf2 {
            self.prev = Some((t_old, dt));
        }
        Ok(info)
    }

    /// The step's inputs: a positive Δt, one conductance (and half) per pipe, radiation
    /// coefficients matching the gap pipes.
    fn check_step(&self, dt: f64, conductance: &[f64], halves: Option<&[PipeConductance]>) -> Result<(), SolveError> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(SolveError::new("heat step", format!("time step {dt} s is not positive")));
        }
        if conductance.len() != self.pipes.len()
            || halves.is_some_and(|h| h.len() != self.pipes.len())
            || !(self.gap_radiation.is_empty() || self.gap_radiation.len() == self.pipes.len() - self.contact_pipes)
        {
            return Err(SolveError::new("heat step", format!("{} conductances for {} pipes", conductance.len(), self.pipes.len())));
        }
        Ok(())
    }

    /// The scheme's coefficients for a step of `dt` over `n` particles (module docs).
    fn coefficients(&self, dt: f64, n: usize) -> Coefficients {
        let (a0, a1, a2, w, prev) = match (self.scheme, &self.prev) {
            (Scheme::Bdf2, Some((tp, dtp))) if tp.len() == n => {
                let om = dt / dtp;
                ((1.0 + 2.0 * om) / (1.0 + om), -(1.0 + om), om * om / (1.0 + om), 1.0, Some(tp.clone()))
            }
            (Scheme::CrankNicolson, _) => (1.0, -1.0, 0.0, 0.5, None),
            _ => (1.0, -1.0, 0.0, 1.0, None),
        };
        Coefficients { a0, a1, a2, w, prev }
    }

    /// The capacity table and mass of particle `i` if its c(T) is tabulated (enthalpy form, eqs.
    /// P1–P2).
    fn table(&self, i: usize) -> Option<(&Table, f64)> {
        self.props.as_ref().and_then(|p| p.capacity_table(i).map(|t| (t, p.mass[i])))
    }

    /// Whether a step iterates (Picard): properties or gap radiation.
    fn nonlinear(&self) -> bool {
        self.props.is_some() || !self.gap_radiation.is_empty()
    }

    /// The pipe conductances at `temps` (κ(T) and gap radiation applied).
    fn pipes_now(&self, temps: &[f64], conductance: &[f64], halves: Option<&[PipeConductance]>) -> Vec<f64> {
        pipe_values(&self.pipes, self.contact_pipes, self.props.as_ref(), &self.gap_radiation, temps, conductance, halves)
    }

    /// The right-hand side known at the start of the step, `r` (storage part, with c(T) the BDF2
    /// history term a2 ΔH^n, plus the explicit half for Crank–Nicolson), and g(T^n) [W].
    fn explicit_part(&self, co: &Coefficients, t: f64, dt: f64, t_old: &[f64], conductance: &[f64], halves: Option<&[PipeConductance]>) -> (Vec<f64>, f64) {
        let nf = self.free.len();
        let (a1, a2, w) = (co.a1, co.a2, co.w);
        let mut rhs0 = vec![0.0; nf];
        for (l, &i) in self.free.iter().enumerate() {
            let i = i as usize;
            if let Some((tab, m)) = self.table(i) {
                if let Some(tp) = &co.prev {
                    rhs0[l] = a2 * m * tab.integral(tp[i], t_old[i]) / dt;
                }
                continue;
            }
            let c = self.capacity[i] / dt;
            let mut r = -c * a1 * t_old[i];
            if let Some(tp) = &co.prev {
                r -= c * a2 * tp[i];
            }
            rhs0[l] = r;
        }
        let mut g_old = 0.0;
        if w < 1.0 {
            let mut f_old = vec![0.0; nf];
            let k_old = if halves.is_some() || !self.gap_radiation.is_empty() { self.pipes_now(t_old, conductance, halves) } else { conductance.to_vec() };
            g_old = self.rates(t_old, t, &k_old, &mut f_old);
            for l in 0..nf {
                rhs0[l] += (1.0 - w) * f_old[l];
            }
        }
        (rhs0, g_old)
    }

    /// The matrix (diagonal `diag0`, values of `pattern_len` entries) and right-hand side without
    /// radiation, for storage coefficients `cap` (a0 C/Δt per free particle), extra storage
    /// right-hand side `cap_rhs` and pipe conductances `k`.
    fn assemble(&self, sys: &StepSystem, pattern_len: usize, cap: &[f64], cap_rhs: Option<&[f64]>, k: &[f64], temps: &[f64]) -> Result<Assembled, SolveError> {
        let nf = self.free.len();
        let w = sys.co.w;
        let (tg, _, hc, _) = sys.furnace;
        let mut diag0 = vec![0.0; nf];
        let mut vals = vec![0.0; pattern_len];
        let mut rhs_c = sys.rhs0.clone();
        if let Some(cr) = cap_rhs {
            for l in 0..nf {
                rhs_c[l] += cr[l];
            }
        }
        for (l, &i) in self.free.iter().enumerate() {
            let i = i as usize;
            let a = self.sources.exposed_area[i];
            diag0[l] = cap[l] + w * hc * a;
            rhs_c[l] += w * (hc * a * tg + self.sources.power[i]);
        }
        for (p, &[i, j]) in self.pipes.iter().enumerate() {
            let k = k[p];
            if !(k >= 0.0 && k.is_finite()) {
                return Err(SolveError::new("heat assembly", format!("pipe {p} ({i}–{j}) has conductance {k} W/K")));
            }
            let (li, lj) = (self.local[i as usize], self.local[j as usize]);
            if li != NONE {
                diag0[li as usize] += w * k;
                if lj == NONE {
                    rhs_c[li as usize] += w * k * temps[j as usize];
                }
            }
            if lj != NONE {
                diag0[lj as usize] += w * k;
                if li == NONE {
                    rhs_c[lj as usize] += w * k * temps[i as usize];
                }
            }
            let e = self.pipe_entry[p];
            if e != NONE {
                vals[e as usize] -= w * k;
            }
        }
        Ok(Assembled { diag0, vals, rhs: rhs_c })
    }

    /// Picard re-assembly at the iterate `x` (free particles' temperatures): the secant capacity
    /// C(T^n, T*) (eq. P2) into `cap`, κ(T*) (eq. P4) and the gap radiation; `work` holds the
    /// temperatures with the iterate. Returns the system and the pipe conductances.
    fn picard_assembly(&self, sys: &StepSystem, pattern_len: usize, x: &[f64], cap: &mut [f64], work: &mut [f64]) -> Result<(Assembled, Vec<f64>), SolveError> {
        let nf = self.free.len();
        for (l, &i) in self.free.iter().enumerate() {
            work[i as usize] = x[l];
        }
        let mut cap_rhs = vec![0.0; nf];
        for (l, &i) in self.free.iter().enumerate() {
            let i = i as usize;
            if let Some((tab, m)) = self.table(i) {
                let cs = sys.co.a0 * m * tab.mean(sys.t_old[i], x[l]) / sys.dt;
                cap[l] = cs;
                cap_rhs[l] = cs * sys.t_old[i];
            }
        }
        let k = self.pipes_now(work, sys.conductance, sys.halves);
        let a = self.assemble(sys, pattern_len, cap, Some(&cap_rhs), &k, work)?;
        Ok((a, k))
    }

    /// The solve of the step: radiation Newton about the iterate and (with properties or gap
    /// radiation) Picard iteration, to `radiation_tol`; `temps` are the temperatures with the
    /// Dirichlet particles at t^{n+1}. Returns the free particles' temperatures, the last pipe
    /// conductances and the step's report (solver part).
    fn iterate(
        &self,
        sys: &StepSystem,
        pattern: &SpdPattern,
        factor: &mut Option<SpdFactor>,
        temps: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>, HeatStepInfo), SolveError> {
        let nf = self.free.len();
        let nonlinear = self.nonlinear();
        let radiation = self.has_radiation();
        let ta = Instant::now();
        let pattern_len = pattern.len();
        let mut cap: Vec<f64> = self.free.iter().map(|&i| sys.co.a0 * self.capacity[i as usize] / sys.dt).collect();
        let mut a = if nonlinear { Assembled::default() } else { self.assemble(sys, pattern_len, &cap, None, sys.conductance, temps)? };
        let mut info = HeatStepInfo { assemble_seconds: ta.elapsed().as_secs_f64(), ..Default::default() };
        let mut x: Vec<f64> = self.free.iter().map(|&i| sys.t_old[i as usize]).collect();
        let max_iter = if nonlinear {
            50
        } else if radiation {
            20
        } else {
            1
        };
        let mut history = Vec::new();
        let mut k_last = sys.conductance.to_vec();
        let mut work = temps.to_vec();
        for it in 1..=max_iter {
            if nonlinear {
                let ta = Instant::now();
                (a, k_last) = self.picard_assembly(sys, pattern_len, &x, &mut cap, &mut work)?;
                info.assemble_seconds += ta.elapsed().as_secs_f64();
            }
            let mut b = a.rhs.clone();
            a.vals[..nf].copy_from_slice(&a.diag0[..nf]);
            if radiation {
                self.linearise_radiation(sys, &x, &mut a.vals, &mut b);
            }
            let reuse = factor.as_ref().is_some_and(|f| f.values == a.vals);
            if !reuse {
                *factor = Some(pattern.factorize(&a.vals)?);
            }
            info.reused_factor = reuse;
            let f = factor.as_ref().unwrap();
            info.solve = f.solve_in_place(pattern, &mut b)?;
            info.solve.factor_seconds = if !reuse { f.factor_seconds } else { 0.0 };
            info.iterations = it;
            let dmax = b.iter().zip(&x).map(|(a, c)| (a - c).abs()).fold(0.0, f64::max);
            let tmax = b.iter().map(|v| v.abs()).fold(0.0, f64::max);
            x = b;
            history.push(dmax / tmax.max(1e-300));
            if !(radiation || nonlinear) || dmax <= self.radiation_tol * tmax {
                return Ok((x, k_last, info));
            }
            if x.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                break;
            }
        }
        let stage = if nonlinear { "radiation Newton / temperature-dependent properties (Picard)" } else { "radiation Newton" };
        Err(SolveError {
            stage: stage.into(),
            message: format!("no convergence in {max_iter} iterations (max|ΔT| ≤ thermal.radiation_tolerance · max T)"),
            residuals: history,
        })
    }

    /// Furnace radiation linearised about the iterate `x` (module docs): `+4εσA T*³` on the
    /// diagonal of `vals`, `+εσA (T_wall⁴ + 3T*⁴)` on `b`.
    fn linearise_radiation(&self, sys: &StepSystem, x: &[f64], vals: &mut [f64], b: &mut [f64]) {
        let (_, tw4, _, eps) = sys.furnace;
        for (l, &i) in self.free.iter().enumerate() {
            let a = self.sources.exposed_area[i as usize];
            if a > 0.0 {
                let ts = x[l];
                let s = sys.co.w * eps * STEFAN_BOLTZMANN * a;
                vals[l] += 4.0 * s * ts.powi(3);
                b[l] += s * (tw4 + 3.0 * ts.powi(4));
            }
        }
    }

    /// Energy accounts of the step ending at `t1` with `temps` (module docs): heat in, the
    /// scheme's stored-heat change and the plain one [J].
    fn energy(&self, sys: &StepSystem, t1: f64, temps: &[f64], k_last: &[f64], g_old: f64) -> (f64, f64, f64) {
        let Coefficients { a0, a1, a2, w, .. } = sys.co;
        let (t_old, bdf_prev) = (sys.t_old, &sys.co.prev);
        let mut f_new = vec![0.0; self.free.len()];
        let g_new = self.rates(temps, t1, k_last, &mut f_new);
        let heat_in = sys.dt * (w * g_new + (1.0 - w) * g_old);
        let mut stored = 0.0;
        let mut plain = 0.0;
        for &i in &self.free {
            let i = i as usize;
            if let Some((tab, m)) = self.table(i) {
                // eq. P1: a0 (H^{n+1} − H^n) − a2 (H^n − H^{n−1})
                let dh = m * tab.integral(t_old[i], temps[i]);
                let mut s = a0 * dh;
                if let Some(tp) = bdf_prev {
                    s -= a2 * m * tab.integral(tp[i], t_old[i]);
                }
                stored += s;
                plain += dh;
                continue;
            }
            let c = self.capacity[i];
            let mut s = c * (a0 * temps[i] + a1 * t_old[i]);
            if let Some(tp) = bdf_prev {
                s += c * a2 * tp[i];
            }
            stored += s;
            plain += c * (temps[i] - t_old[i]);
        }
        (heat_in, stored, plain)
    }
}

/// The scheme's coefficients of one step: `M = a0 C/Δt`, weight `w` of f(T^{n+1}), history
/// coefficients `a1`, `a2` and the BDF2 history T^{n−1} (module docs).
struct Coefficients {
    a0: f64,
    a1: f64,
    a2: f64,
    w: f64,
    prev: Option<Vec<f64>>,
}

/// What a step's iterations hold fixed: coefficients, Δt, T^n, the known right-hand side, the
/// furnace at t^{n+1} (gas T, wall T⁴, h_c, ε) and the given pipe conductances (and halves).
struct StepSystem<'a> {
    co: Coefficients,
    dt: f64,
    t_old: &'a [f64],
    rhs0: Vec<f64>,
    furnace: (f64, f64, f64, f64),
    conductance: &'a [f64],
    halves: Option<&'a [PipeConductance]>,
}

/// An assembled system without radiation: diagonal, matrix values, right-hand side.
#[derive(Default)]
struct Assembled {
    diag0: Vec<f64>,
    vals: Vec<f64>,
    rhs: Vec<f64>,
}

/// Conductances [W/K] of `pipes` at `temps`: the given `conductance`; with `halves` and κ(T)
/// tables, the contact pipes `[0, nc)` rescaled by eq. P4; the gap pipes `[nc, ..)` plus their
/// radiation `c (T_i² + T_j²)(T_i + T_j)` (H23) when `radiation` is not empty.
fn pipe_values(
    pipes: &[[u32; 2]],
    nc: usize,
    props: Option<&ThermalProperties>,
    radiation: &[f64],
    temps: &[f64],
    conductance: &[f64],
    halves: Option<&[PipeConductance]>,
) -> Vec<f64> {
    let mut k: Vec<f64> = match (halves, props) {
        (Some(h), Some(pr)) => pipes
            .iter()
            .zip(h)
            .enumerate()
            .map(|(p, (&[i, j], pc))| if p < nc { pr.pipe(pc, i as usize, j as usize, temps[i as usize], temps[j as usize]) } else { conductance[p] })
            .collect(),
        _ => conductance.to_vec(),
    };
    for (q, &c) in radiation.iter().enumerate() {
        let [i, j] = pipes[nc + q];
        k[nc + q] += crate::heat::gap::radiative_conductance(c, temps[i as usize], temps[j as usize]);
    }
    k
}
