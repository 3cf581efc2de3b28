//! The mechanics adapter of the step (stage 4): the bonded system of [`crate::mechanics`] built
//! for the compact's particles and contacts, its solves and its counters.

use super::{Contacts, MechanicsSettings};
use crate::error::{Error, ModelError};
use crate::mechanics::periodic::{CellControl, CellInput, CellStep};
use crate::mechanics::{BondedSystem, Constraints, MechParams, NodalLoad, StepInput};
use crate::models::diffusion7 as d7;
use nalgebra::Vector3;

/// Stage 4: the bonded system, built at the first solve and re-topologised when contacts appear.
pub struct MechanicsStage {
    settings: MechanicsSettings,
    pub(super) sys: Option<BondedSystem>,
    bonds: usize,
    /// Accumulated rotations [rad].
    pub rotation: Vec<Vector3<f64>>,
    /// With sliding: the stored tangential link force per contact, global axes [N] (B27)
    /// (checkpointed); empty without sliding.
    pub tangential: Vec<Vector3<f64>>,
    /// With sliding: the stored link moment per contact, global axes [N·m] (B30)
    /// (checkpointed); empty without sliding.
    pub moment: Vec<Vector3<f64>>,
    /// With sliding: the viscosities of every neck ((B24), (B29), (B30)) and the step [s] of the
    /// next solves, set by the caller before each ([`Self::set_sliding`]).
    sliding: Option<(crate::mechanics::sliding::NeckViscosities, f64)>,
    /// Newton iterations and factorisations so far.
    pub newton_iterations: u64,
    pub factorizations: u64,
    pub max_residual: f64,
    /// Where the mechanics time goes (this process only; not checkpointed).
    pub profile: MechProfile,
}

/// Counters and wall times of the mechanics stage, summed over steps (summary `mechanics_profile`).
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct MechProfile {
    /// Topology analyses (bond set changed) [1].
    pub topology_changes: u64,
    /// Bond-set changes served by the low-rank update of the kept factor (`update_rank`,
    /// docs/coupled.md "Low-rank update of the factor") [1]; left out when 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub updates: u64,
    /// CG iterations (stale-factor or AMG preconditioned) [1].
    pub cg_iterations: u64,
    /// Wall times [s]: topology analysis, symbolic factorisation, assembly, numeric factorisation,
    /// solves (triangular or CG).
    pub analysis_s: f64,
    pub symbolic_s: f64,
    pub assemble_s: f64,
    pub factor_s: f64,
    pub solve_s: f64,
    /// Whole mechanics steps [s].
    pub total_s: f64,
}

fn is_zero(v: &u64) -> bool {
    *v == 0
}

impl MechanicsStage {
    pub fn new(n: usize, settings: &MechanicsSettings) -> Self {
        MechanicsStage {
            settings: settings.clone(),
            sys: None,
            bonds: 0,
            rotation: vec![Vector3::zeros(); n],
            tangential: Vec::new(),
            moment: Vec::new(),
            sliding: None,
            newton_iterations: 0,
            factorizations: 0,
            max_residual: 0.0,
            profile: MechProfile::default(),
        }
    }

    /// Builds the bonded system with the plane constraints of the initial packing.
    pub fn build(&mut self, p: &crate::particles::Particles, young: f64, poisson: f64) -> Result<(), Error> {
        // a periodic cell has no planes: its gauge is set by the periodic analysis (B19)
        let cons = if self.settings.constrain_planes && self.settings.cell.is_none() {
            Constraints::principal_planes(&p.position, &p.radius, self.settings.plane_gap)?
        } else {
            Constraints::none(p.len())
        };
        let params = MechParams {
            young_modulus: young,
            poisson_ratio: poisson,
            solver: self.settings.solver,
            reuse_factor: self.settings.reuse_factor,
            rtol: self.settings.rtol,
            warm_start: self.settings.warm_start,
            warm_start_depth: self.settings.warm_start_depth,
            amg_keep_on_new_bonds: self.settings.amg_keep_on_new_bonds,
            update_rank: self.settings.update_rank,
            ..Default::default()
        };
        self.sys = Some(BondedSystem::new(p.len(), params, cons)?);
        Ok(())
    }

    /// The viscosities of every neck and the step `dt` [s] of the next solves (docs/mechanics.md
    /// (B24)–(B30)); None: elastic links.
    pub(super) fn set_sliding(&mut self, sliding: Option<(crate::mechanics::sliding::NeckViscosities, f64)>) {
        self.sliding = sliding;
    }

    /// Puts the sliding data into the bonded system for a solve: with the stored forces of the
    /// contacts (`commit`: a step that advances them; new contacts store nothing) or without (a
    /// load distribution (P3), which sees the effective links only).
    fn relaxation_for(&self, commit: bool, contacts: usize) -> Option<crate::mechanics::sliding::Relaxation> {
        let (visc, dt) = self.sliding.as_ref()?;
        let (mut stored, mut stored_moment, mut network) = (Vec::new(), Vec::new(), Vec::new());
        if commit {
            stored = self.tangential.clone();
            stored.resize(contacts, Vector3::zeros());
            if !visc.rolling.is_empty() {
                stored_moment = self.moment.clone();
                stored_moment.resize(contacts, Vector3::zeros());
            }
        } else if visc.network.len() == contacts {
            network = visc.network.clone();
        }
        Some(crate::mechanics::sliding::Relaxation {
            dt: *dt,
            viscosity: visc.tangential.clone(),
            stored,
            network,
            rolling: visc.rolling.clone(),
            stored_moment,
        })
    }

    /// Forgets the cached factor, so that the next step factorises afresh (done at checkpoints, so
    /// that a resumed run repeats the uninterrupted one bit for bit).
    pub fn drop_factor(&mut self) -> Result<(), Error> {
        if let Some(sys) = self.sys.as_mut() {
            sys.drop_factor();
        }
        Ok(())
    }

    /// Solves the step: displacement increments per particle and the axial approach ξ per contact.
    /// `radii`: the thermally expanded radii (docs/coupled.md (X6)) that set R_m of the links and of
    /// the load (F5); None: the particles' own.
    pub(super) fn solve(
        &mut self,
        p: &crate::particles::Particles,
        contacts: &Contacts,
        approach: &[f64],
        external: Option<&[NodalLoad]>,
        radii: Option<&[f64]>,
    ) -> Result<(Vec<Vector3<f64>>, Vec<f64>), Error> {
        let relax = self.relaxation_for(true, contacts.len());
        let sliding = relax.is_some();
        let sys = self.synced(contacts)?;
        sys.set_relaxation(relax);
        let y4_y7 = bar_lengths(contacts);
        let load = load_increments(sys, contacts, approach, radii);
        let inp = StepInput { positions: &p.position, radii: radii.unwrap_or(&p.radius), y4_y7: &y4_y7, load: &load, external };
        let out = step_or_refactor(sys, &inp);
        sys.set_relaxation(None);
        let out = out?;
        for (r, d) in self.rotation.iter_mut().zip(&out.dtheta) {
            *r += d;
        }
        if sliding {
            self.tangential = out.tangential.clone();
            self.moment = out.moment.clone();
        }
        self.count(&out.info);
        Ok((out.du, out.xi))
    }

    /// The load distribution of docs/pressure.md (P3): the bonded equilibrium under the nodal
    /// forces `loads` alone (no sintering loads), at the current geometry; returns per contact the
    /// axial force (compressive positive) [N] and the force on A exerted by B (global axes) [N].
    /// Positions and rotations are not changed.
    pub(super) fn distribute(
        &mut self,
        p: &crate::particles::Particles,
        contacts: &Contacts,
        loads: &[NodalLoad],
    ) -> Result<(Vec<f64>, Vec<Vector3<f64>>), Error> {
        let relax = self.relaxation_for(false, contacts.len());
        let sys = self.synced(contacts)?;
        sys.set_relaxation(relax);
        let y4_y7 = bar_lengths(contacts);
        let zero = vec![0.0; contacts.len()];
        let out = step_or_refactor(sys, &StepInput { positions: &p.position, radii: &p.radius, y4_y7: &y4_y7, load: &zero, external: Some(loads) });
        // the links the solve used: elastic, Maxwell (B25), (B30) or the viscous network (B29)
        let links = sys.link_stiffnesses(&p.radius);
        sys.set_relaxation(None);
        let out = out?;
        let r_scale = p.radius.iter().sum::<f64>() / p.len().max(1) as f64;
        let mut normal = Vec::with_capacity(contacts.len());
        let mut force = Vec::with_capacity(contacts.len());
        for (k, &[a, b]) in contacts.pairs.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            let [y4, y7] = y4_y7[k];
            let g = crate::mechanics::BondGeometry::new(&p.position[a], &p.position[b], y4, y7)?;
            let kl = links[k];
            let mut y = nalgebra::SMatrix::<f64, 12, 1>::zeros();
            for d in 0..3 {
                y[d] = out.du[a][d];
                y[3 + d] = out.dtheta[a][d] * r_scale;
                y[6 + d] = out.du[b][d];
                y[9 + d] = out.dtheta[b][d] * r_scale;
            }
            let fl = crate::mechanics::bond::link_forces(&g, &kl, r_scale, &y);
            // local [F1, F2, F3] with F3 > 0 compression; the link pushes A by −Rᵀ·F_local
            let rot = crate::mechanics::frame(&g.e3);
            normal.push(fl[2]);
            force.push(-(rot.transpose() * Vector3::new(fl[0], fl[1], fl[2])));
        }
        self.count(&out.info);
        Ok((normal, force))
    }

    /// The periodic step (docs/mechanics.md (B13)–(B21)) for the eigen-approach `approach` [m]
    /// per contact and the cell controls: the whole displacement increment per particle [m], ξ
    /// per contact [m] and the cell's part of the result.
    pub(super) fn solve_periodic(
        &mut self,
        p: &crate::particles::Particles,
        contacts: &Contacts,
        approach: &[f64],
        cell: &nalgebra::Matrix3<f64>,
        controls: &[CellControl],
    ) -> Result<(Vec<Vector3<f64>>, Vec<f64>, CellStep), Error> {
        self.periodic_step(p, contacts, approach, cell, controls, true)
    }

    /// [`Self::solve_periodic`]; `commit`: a step (rotations and stored tangential forces
    /// advance), else a load distribution (nothing changes).
    fn periodic_step(
        &mut self,
        p: &crate::particles::Particles,
        contacts: &Contacts,
        approach: &[f64],
        cell: &nalgebra::Matrix3<f64>,
        controls: &[CellControl],
        commit: bool,
    ) -> Result<(Vec<Vector3<f64>>, Vec<f64>, CellStep), Error> {
        let relax = self.relaxation_for(commit, contacts.len());
        let sliding = relax.is_some();
        let sys = self.synced(contacts)?;
        sys.set_relaxation(relax);
        let y4_y7 = bar_lengths(contacts);
        let load = load_increments(sys, contacts, approach, None);
        let inp = StepInput { positions: &p.position, radii: &p.radius, y4_y7: &y4_y7, load: &load, external: None };
        let ci = CellInput { cell, controls };
        let result = match sys.step_periodic(&inp, &ci) {
            Err(Error::Solve(_)) => {
                sys.drop_factor();
                sys.step_periodic(&inp, &ci)
            }
            r => r,
        };
        sys.set_relaxation(None);
        let (out, cs) = result?;
        if commit {
            for (r, d) in self.rotation.iter_mut().zip(&out.dtheta) {
                *r += d;
            }
            if sliding {
                self.tangential = out.tangential.clone();
                self.moment = out.moment.clone();
            }
        }
        self.count(&out.info);
        Ok((out.du, out.xi, cs))
    }

    /// The load distribution of docs/pressure.md (P3) on a periodic cell: the bonded equilibrium
    /// under the cell stress `stress` [Pa] alone (strain-controlled components held), at the
    /// current geometry; the axial force per contact [N], compression positive. Nothing moves.
    pub(super) fn distribute_periodic(
        &mut self,
        p: &crate::particles::Particles,
        contacts: &Contacts,
        cell: &nalgebra::Matrix3<f64>,
        controls: &[CellControl],
    ) -> Result<Vec<f64>, Error> {
        let zero = vec![0.0; contacts.len()];
        let (_, _, cs) = self.periodic_step(p, contacts, &zero, cell, controls, false)?;
        Ok(cs.axial_force)
    }

    /// The built bonded system with the bond set of `contacts` (re-topologised when contacts
    /// appeared since the last solve).
    fn synced(&mut self, contacts: &Contacts) -> Result<&mut BondedSystem, Error> {
        let sys = self.sys.as_mut().ok_or_else(|| ModelError::new("mechanics: the bonded system was not built"))?;
        if self.bonds != contacts.len() {
            sys.set_topology(&contacts.pairs)?;
            self.bonds = contacts.len();
        }
        Ok(sys)
    }

    /// Adds a solve's counters and times to the stage's totals.
    fn count(&mut self, out_info: &crate::mechanics::MechInfo) {
        self.newton_iterations += out_info.newton_iterations as u64;
        self.factorizations += out_info.factorizations as u64;
        let (pr, i) = (&mut self.profile, out_info);
        pr.topology_changes += i.topology_rebuilt as u64;
        pr.cg_iterations += i.pcg_iterations as u64;
        pr.updates += i.updates as u64;
        pr.analysis_s += i.analysis_seconds;
        pr.symbolic_s += i.symbolic_seconds;
        pr.assemble_s += i.assemble_seconds;
        pr.factor_s += i.factor_seconds;
        pr.solve_s += i.solve_seconds;
        pr.total_s += i.total_seconds;
        // a step solved by its warm start alone (docs/mechanics.md (B12)) has no Newton residual
        self.max_residual = self.max_residual.max(out_info.residuals.last().copied().unwrap_or(out_info.warm_start));
    }
}

/// One bonded step; a stale factor that fails to converge (a SolveError, which ends a run) is
/// dropped and the step repeated once with a fresh analysis and factorisation (seen under an
/// applied load, docs/pressure.md). Runs that converge are not affected.
fn step_or_refactor(sys: &mut BondedSystem, inp: &StepInput) -> Result<crate::mechanics::MechStep, Error> {
    match sys.step(inp) {
        Err(Error::Solve(_)) => {
            sys.drop_factor();
            sys.step(inp)
        }
        r => r,
    }
}

/// `[y4, y7]` per contact at its last accepted state [m] (the bar halves of the bonds, (F1)).
fn bar_lengths(contacts: &Contacts) -> Vec<[f64; 2]> {
    contacts.state.iter().map(|c| [c.y_prev[3], c.y_prev[6]]).collect()
}

/// The load increments (F5) [N] of the eigen-approaches `approach` [m], with each link's own E so
/// that E cancels from the approach per bond; `radii`: the thermally expanded radii that set R_m
/// (docs/coupled.md (X6)), None: the contacts' own initial radii.
fn load_increments(sys: &BondedSystem, contacts: &Contacts, approach: &[f64], radii: Option<&[f64]>) -> Vec<f64> {
    contacts
        .state
        .iter()
        .zip(approach)
        .zip(&contacts.pairs)
        .map(|((c, &a), &[i, j])| {
            let r_m = radii.map_or(c.r_mean(), |r| 0.5 * (r[i as usize] + r[j as usize]));
            d7::load_increment(a, 0.0, r_m, sys.link_elastic(i, j)[0])
        })
        .collect()
}
