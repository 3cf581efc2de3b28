//! hypre's BoomerAMG as the preconditioner of hypre's PCG on the bonded stiffness
//! (`mechanics.solver = "hypre"`, cargo feature `hypre`; docs/coupled.md "hypre's BoomerAMG against our AMG").
//!
//! The system handed to hypre keeps **six unknowns per node** so that BoomerAMG's nodal (systems)
//! coarsening applies (`HYPRE_BoomerAMGSetNumFunctions(6)`, `SetNodal`): the nodes are the
//! particles that are not fully fixed (rattlers and pinned particles are left out, as in our AMG),
//! numbered in particle order, unknown `6k + p` the DOF `p` of node `k`; a fixed DOF of a free node
//! is a Dirichlet row `K_pp·y_p = 0` (its diagonal entry of the stiffness, no off-diagonal entries),
//! which keeps the row scale of its node and gives `y_p = 0`. With `MECH_HYPRE=rbm=1` (an
//! experiment switch, off by default because it was slower, docs/coupled.md) the **rigid-body
//! rotations** about the centroid of the nodes in the scaled unknowns `[u, r̄θ]` (the last three
//! columns of [`super::amg::rigid_modes`], rows of fixed DOF zero) are BoomerAMG's interpolation
//! vectors (`HYPRE_BoomerAMGSetInterpVectors`, variant 2 "GM approach 2"); the translations are the
//! constants per unknown that the unknown-based interpolation already reproduces. The options are
//! those of MFEM's `HypreBoomerAMG::SetElasticityOptions` (mfem/mfem, linalg/hypre.cpp: nodal 4,
//! nodal_diag 1, coarse relaxation 8, interp_vec_variant 2, q_max 4, smoothed interpolation
//! vectors, interp_refine 1; `SetSystemsOptions`: aggressive levels 0, strength 0.5) on its
//! defaults (HMIS coarsening 10, ext+i interpolation 6 with at most 4 entries per row, l1-Gauss–Seidel
//! relaxation 8, one sweep, one V-cycle per preconditioner application).
//!
//! PCG is hypre's (`HYPRE_ParCSRPCG`, two-norm stopping test `‖r‖₂ ≤ tol·‖b‖₂`) with the inner
//! tolerance of our CG in the same Newton loop (docs/mechanics.md (B10)), so the two are compared
//! at equal tolerance. The hierarchy is built afresh at every step (hypre's setup is tied to the
//! matrix it was built for).
//!
//! **MPI**: hypre is called on `MPI_COMM_SELF` (one process solves its system alone, also under
//! `mpirun`); MPI is initialised once per process (`MPI_Init_thread`, serialized calls) unless the
//! host program already did, and finalised at exit. hypre is not thread-safe: one global lock
//! serialises every call. Open MPI refuses `mpirun` as root unless `OMPI_ALLOW_RUN_AS_ROOT=1` and
//! `OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1` are set; as root they are set here before `MPI_Init` when
//! unset (a plain singleton run did not need them with Open MPI 4.1, measured 2026-12-07).

use super::constraints::TopologyReport;
use super::solve::SolverUsed;
use super::{BlockMatrix, BondedSystem, MechInfo};
use crate::error::{ConfigError, Error};
use nalgebra::Vector3;

/// True when this build links hypre (cargo feature `hypre`).
pub const AVAILABLE: bool = cfg!(feature = "hypre");

/// The error of `mechanics.solver = "hypre"` in a build without the feature.
pub fn feature_missing(key: &str) -> ConfigError {
    ConfigError::invalid(format!(
        "{key} = \"hypre\": this sinterdem was built without hypre; allowed here: auto, cholesky, cg, amg. \
         Build with the `hypre` cargo feature (it needs the system hypre library, Debian: `apt-get install libhypre-dev`): \
         `cargo build --release --features h5,hypre` (docs/coupled.md \"hypre's BoomerAMG against our AMG\")"
    ))
}

/// Rejects the hypre solver (`key` names it) in a build without the feature.
pub fn check_available(key: &str) -> Result<(), ConfigError> {
    if AVAILABLE { Ok(()) } else { Err(feature_missing(key)) }
}

impl BondedSystem {
    /// Newton with hypre's BoomerAMG-preconditioned PCG from `x` (the warm start, whose residual
    /// is `r0` when given), the inner tolerance as [`BondedSystem::newton_pcg`]'s (B10); a fresh
    /// hierarchy per Newton iteration. Without the feature: the configuration error.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn newton_hypre(
        &mut self,
        rep: &TopologyReport,
        positions: &[Vector3<f64>],
        r_scale: f64,
        blocks: &BlockMatrix,
        b: &[f64],
        b_norm: f64,
        x: &mut [f64],
        r0: Option<Vec<f64>>,
        info: &mut MechInfo,
    ) -> Result<(), Error> {
        check_available("mechanics.solver")?;
        info.solver = SolverUsed::Hypre;
        #[cfg(not(feature = "hypre"))]
        {
            let _ = (rep, positions, r_scale, blocks, b, b_norm, x, r0);
            Ok(())
        }
        #[cfg(feature = "hypre")]
        {
            let op = super::amg::FineOp { blocks, pairs: &self.pairs, inc: &self.inc, fixed: &rep.fixed };
            let max_iter = self.params.pcg_max_iter;
            // a fresh BoomerAMG hierarchy per Newton iteration (hypre's solve starts from dx = 0)
            super::newton::newton_inexact(&self.params, &op, b, b_norm, x, r0, info, "hypre BoomerAMG-PCG", |r, dx, tol, info| {
                let s = imp::solve(&op, positions, r_scale, r, dx, tol, max_iter)?;
                info.assemble_seconds += s.assemble_seconds;
                info.factor_seconds += s.setup_seconds;
                info.solve_seconds += s.solve_seconds;
                info.pcg_iterations += s.iterations;
                info.amg_builds += 1;
                Ok(())
            })
        }
    }
}

#[cfg(feature = "hypre")]
mod ffi {
    //! The few hypre 2.26 and MPI functions used (HYPRE_Int and HYPRE_BigInt are 32-bit `int`,
    //! HYPRE_Real `double` in Debian's build: HYPRE_BIGINT and HYPRE_MIXEDINT undefined in
    //! HYPRE_config.h).
    #![allow(non_snake_case, non_upper_case_globals, dead_code)]
    use std::os::raw::{c_char, c_int, c_void};

    pub type HypreInt = c_int;
    pub type Handle = *mut c_void;
    pub type MpiComm = *mut c_void;
    pub type SolverFn = unsafe extern "C" fn(Handle, Handle, Handle, Handle) -> HypreInt;

    /// `HYPRE_PARCSR` (HYPRE.h).
    pub const HYPRE_PARCSR: HypreInt = 5555;
    /// `MPI_THREAD_SERIALIZED` (Open MPI's mpi.h enum: SINGLE 0, FUNNELED 1, SERIALIZED 2).
    pub const MPI_THREAD_SERIALIZED: c_int = 2;

    unsafe extern "C" {
        /// Open MPI's predefined communicator behind `MPI_COMM_SELF` (mpi.h: `&ompi_mpi_comm_self`).
        pub static ompi_mpi_comm_self: u8;
        pub fn MPI_Initialized(flag: *mut c_int) -> c_int;
        pub fn MPI_Finalized(flag: *mut c_int) -> c_int;
        pub fn MPI_Init_thread(argc: *mut c_int, argv: *mut *mut *mut c_char, required: c_int, provided: *mut c_int) -> c_int;
        pub fn MPI_Finalize() -> c_int;
        pub fn atexit(f: extern "C" fn()) -> c_int;

        pub fn HYPRE_Init() -> HypreInt;
        pub fn HYPRE_ClearAllErrors() -> HypreInt;
        pub fn HYPRE_DescribeError(ierr: HypreInt, descr: *mut c_char);

        pub fn HYPRE_IJMatrixCreate(comm: MpiComm, ilower: HypreInt, iupper: HypreInt, jlower: HypreInt, jupper: HypreInt, m: *mut Handle) -> HypreInt;
        pub fn HYPRE_IJMatrixSetObjectType(m: Handle, t: HypreInt) -> HypreInt;
        pub fn HYPRE_IJMatrixSetRowSizes(m: Handle, sizes: *const HypreInt) -> HypreInt;
        pub fn HYPRE_IJMatrixInitialize(m: Handle) -> HypreInt;
        pub fn HYPRE_IJMatrixSetValues(
            m: Handle,
            nrows: HypreInt,
            ncols: *mut HypreInt,
            rows: *const HypreInt,
            cols: *const HypreInt,
            values: *const f64,
        ) -> HypreInt;
        pub fn HYPRE_IJMatrixAssemble(m: Handle) -> HypreInt;
        pub fn HYPRE_IJMatrixGetObject(m: Handle, obj: *mut Handle) -> HypreInt;
        pub fn HYPRE_IJMatrixDestroy(m: Handle) -> HypreInt;

        pub fn HYPRE_IJVectorCreate(comm: MpiComm, jlower: HypreInt, jupper: HypreInt, v: *mut Handle) -> HypreInt;
        pub fn HYPRE_IJVectorSetObjectType(v: Handle, t: HypreInt) -> HypreInt;
        pub fn HYPRE_IJVectorInitialize(v: Handle) -> HypreInt;
        pub fn HYPRE_IJVectorSetValues(v: Handle, n: HypreInt, idx: *const HypreInt, values: *const f64) -> HypreInt;
        pub fn HYPRE_IJVectorGetValues(v: Handle, n: HypreInt, idx: *const HypreInt, values: *mut f64) -> HypreInt;
        pub fn HYPRE_IJVectorAssemble(v: Handle) -> HypreInt;
        pub fn HYPRE_IJVectorGetObject(v: Handle, obj: *mut Handle) -> HypreInt;
        pub fn HYPRE_IJVectorDestroy(v: Handle) -> HypreInt;

        pub fn HYPRE_BoomerAMGCreate(s: *mut Handle) -> HypreInt;
        pub fn HYPRE_BoomerAMGDestroy(s: Handle) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetup(s: Handle, a: Handle, b: Handle, x: Handle) -> HypreInt;
        pub fn HYPRE_BoomerAMGSolve(s: Handle, a: Handle, b: Handle, x: Handle) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetPrintLevel(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetCoarsenType(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetAggNumLevels(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetRelaxType(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetCycleRelaxType(s: Handle, v: HypreInt, k: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetNumSweeps(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetStrongThreshold(s: Handle, v: f64) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetInterpType(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetPMaxElmts(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetMaxLevels(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetMaxIter(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetTol(s: Handle, v: f64) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetNumFunctions(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetNodal(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetNodalDiag(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetInterpVecVariant(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetInterpVecQMax(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetSmoothInterpVectors(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetInterpRefine(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_BoomerAMGSetInterpVectors(s: Handle, n: HypreInt, vectors: *mut Handle) -> HypreInt;
        pub fn HYPRE_BoomerAMGGetNumIterations(s: Handle, n: *mut HypreInt) -> HypreInt;

        pub fn HYPRE_ParCSRPCGCreate(comm: MpiComm, s: *mut Handle) -> HypreInt;
        pub fn HYPRE_ParCSRPCGDestroy(s: Handle) -> HypreInt;
        pub fn HYPRE_ParCSRPCGSetTol(s: Handle, v: f64) -> HypreInt;
        pub fn HYPRE_ParCSRPCGSetMaxIter(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_ParCSRPCGSetTwoNorm(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_ParCSRPCGSetPrintLevel(s: Handle, v: HypreInt) -> HypreInt;
        pub fn HYPRE_ParCSRPCGSetPrecond(s: Handle, precond: SolverFn, setup: SolverFn, p: Handle) -> HypreInt;
        pub fn HYPRE_ParCSRPCGSetup(s: Handle, a: Handle, b: Handle, x: Handle) -> HypreInt;
        pub fn HYPRE_ParCSRPCGSolve(s: Handle, a: Handle, b: Handle, x: Handle) -> HypreInt;
        pub fn HYPRE_ParCSRPCGGetNumIterations(s: Handle, n: *mut HypreInt) -> HypreInt;
        pub fn HYPRE_ParCSRPCGGetFinalRelativeResidualNorm(s: Handle, r: *mut f64) -> HypreInt;
    }
}

#[cfg(feature = "hypre")]
mod imp {
    use super::ffi::*;
    use crate::error::SolveError;
    use crate::mechanics::amg::{FineOp, rigid_modes};
    use nalgebra::Vector3;
    use std::sync::{Mutex, OnceLock};
    use std::time::Instant;

    /// hypre keeps global state (error flag, memory tracker): one call sequence at a time.
    static LOCK: Mutex<()> = Mutex::new(());
    static INIT: OnceLock<Result<(), String>> = OnceLock::new();

    extern "C" fn finalize_mpi() {
        let mut done = 0;
        // SAFETY: MPI_Finalized may be called at any time; MPI_Finalize once, after MPI_Init.
        unsafe {
            MPI_Finalized(&mut done);
            if done == 0 {
                MPI_Finalize();
            }
        }
    }

    /// MPI (unless the host initialised it) and hypre, once per process.
    fn init() -> Result<(), SolveError> {
        let r = INIT.get_or_init(|| {
            let mut flag = 0;
            // SAFETY: plain MPI/hypre C calls with valid out-pointers; run once (OnceLock).
            unsafe {
                MPI_Initialized(&mut flag);
                if flag == 0 {
                    let root = std::fs::read_to_string("/proc/self/status")
                        .ok()
                        .and_then(|s| s.lines().find(|l| l.starts_with("Uid:")).map(|l| l.split_whitespace().nth(1) == Some("0")))
                        .unwrap_or(false);
                    if root {
                        for v in ["OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM"] {
                            if std::env::var_os(v).is_none() {
                                // SAFETY: set before MPI starts its threads, inside the once-only init;
                                // nothing else in sinterdem reads these variables.
                                std::env::set_var(v, "1");
                            }
                        }
                    }
                    let mut provided = 0;
                    let rc = MPI_Init_thread(std::ptr::null_mut(), std::ptr::null_mut(), MPI_THREAD_SERIALIZED, &mut provided);
                    if rc != 0 {
                        return Err(format!(
                            "MPI_Init_thread failed (code {rc}); as root Open MPI may need OMPI_ALLOW_RUN_AS_ROOT=1 and OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"
                        ));
                    }
                    atexit(finalize_mpi);
                }
                let rc = HYPRE_Init();
                if rc != 0 {
                    return Err(format!("HYPRE_Init failed (hypre error {rc})"));
                }
            }
            Ok(())
        });
        r.clone().map_err(|m| SolveError::new("hypre", m))
    }

    fn comm() -> MpiComm {
        // the address of Open MPI's predefined MPI_COMM_SELF object (what mpi.h's macro is)
        (&raw const ompi_mpi_comm_self) as MpiComm
    }

    /// A hypre call that must return 0; otherwise the error with hypre's description.
    fn ok(rc: HypreInt, what: &str) -> Result<(), SolveError> {
        if rc == 0 {
            return Ok(());
        }
        let mut buf = [0 as std::os::raw::c_char; 256];
        // SAFETY: HYPRE_DescribeError writes a short NUL-terminated text (< 100 bytes) into buf.
        let text = unsafe {
            HYPRE_DescribeError(rc, buf.as_mut_ptr());
            HYPRE_ClearAllErrors();
            std::ffi::CStr::from_ptr(buf.as_ptr()).to_string_lossy().into_owned()
        };
        Err(SolveError::new("hypre", format!("{what} failed (hypre error {rc}: {})", text.trim())))
    }

    /// The hypre objects of one solve, destroyed on drop (every handle null until created).
    struct Objects {
        a: Handle,
        vecs: Vec<Handle>,
        amg: Handle,
        pcg: Handle,
    }

    impl Drop for Objects {
        fn drop(&mut self) {
            // SAFETY: each handle was created by the matching Create call (or is null); the solvers
            // go first, the interpolation vectors after BoomerAMG (as MFEM's ~HypreBoomerAMG).
            unsafe {
                if !self.pcg.is_null() {
                    HYPRE_ParCSRPCGDestroy(self.pcg);
                }
                if !self.amg.is_null() {
                    HYPRE_BoomerAMGDestroy(self.amg);
                }
                for v in &self.vecs {
                    if !v.is_null() {
                        HYPRE_IJVectorDestroy(*v);
                    }
                }
                if !self.a.is_null() {
                    HYPRE_IJMatrixDestroy(self.a);
                }
            }
        }
    }

    /// What one hypre solve did.
    pub struct HypreSolve {
        /// PCG iterations [1].
        pub iterations: usize,
        /// Wall time of the matrix and vector assembly, the PCG/BoomerAMG setup, the PCG solve [s].
        pub assemble_seconds: f64,
        pub setup_seconds: f64,
        pub solve_seconds: f64,
    }

    /// The node numbering: `node[i]` of particle `i` (u32::MAX: fully fixed, left out).
    fn nodes(fixed: &[u8]) -> (Vec<u32>, usize) {
        let mut node = vec![u32::MAX; fixed.len()];
        let mut k = 0;
        for (i, &m) in fixed.iter().enumerate() {
            if m != 63 {
                node[i] = k as u32;
                k += 1;
            }
        }
        (node, k)
    }

    /// The CSR rows of the 6-unknowns-per-node system (module doc): (row sizes, columns, values).
    fn rows(op: &FineOp, node: &[u32]) -> (Vec<HypreInt>, Vec<HypreInt>, Vec<f64>) {
        let (mut sizes, mut cols, mut vals) = (Vec::new(), Vec::new(), Vec::new());
        for (i, &k) in node.iter().enumerate() {
            if k == u32::MAX {
                continue;
            }
            let m = op.fixed[i];
            let d = &op.blocks.diag[i];
            for p in 0..6 {
                let before = cols.len();
                if m & (1 << p) != 0 {
                    let v = d[(p, p)];
                    cols.push((6 * k as usize + p) as HypreInt);
                    vals.push(if v.is_finite() && v > 0.0 { v } else { 1.0 });
                } else {
                    for q in 0..6 {
                        if m & (1 << q) == 0 {
                            cols.push((6 * k as usize + q) as HypreInt);
                            vals.push(d[(p, q)]);
                        }
                    }
                    for &(b, side) in op.inc.of(i) {
                        let pair = op.pairs[b as usize];
                        let j = pair[1 - side as usize] as usize;
                        if node[j] == u32::MAX {
                            continue;
                        }
                        let kb = &op.blocks.off[b as usize];
                        for q in 0..6 {
                            if op.fixed[j] & (1 << q) == 0 {
                                cols.push((6 * node[j] as usize + q) as HypreInt);
                                vals.push(if side == 0 { kb[(p, q)] } else { kb[(q, p)] });
                            }
                        }
                    }
                }
                sizes.push((cols.len() - before) as HypreInt);
            }
        }
        (sizes, cols, vals)
    }

    /// An assembled hypre vector of `values` on rows `0..values.len()`: (IJ handle, ParVector);
    /// the IJ handle joins `store` (destroyed with it).
    fn vector(values: &[f64], store: &mut Vec<Handle>) -> Result<(Handle, Handle), SolveError> {
        let n = values.len() as HypreInt;
        let idx: Vec<HypreInt> = (0..n).collect();
        let mut v: Handle = std::ptr::null_mut();
        let mut obj: Handle = std::ptr::null_mut();
        // SAFETY: hypre IJ vector calls on a vector created here; idx/values hold n entries.
        unsafe {
            ok(HYPRE_IJVectorCreate(comm(), 0, n - 1, &mut v), "HYPRE_IJVectorCreate")?;
            store.push(v);
            ok(HYPRE_IJVectorSetObjectType(v, HYPRE_PARCSR), "HYPRE_IJVectorSetObjectType")?;
            ok(HYPRE_IJVectorInitialize(v), "HYPRE_IJVectorInitialize")?;
            ok(HYPRE_IJVectorSetValues(v, n, idx.as_ptr(), values.as_ptr()), "HYPRE_IJVectorSetValues")?;
            ok(HYPRE_IJVectorAssemble(v), "HYPRE_IJVectorAssemble")?;
            ok(HYPRE_IJVectorGetObject(v, &mut obj), "HYPRE_IJVectorGetObject")?;
        }
        Ok((v, obj))
    }

    /// An integer override of `MECH_HYPRE` (experiments, as `MECH_AMG` for our AMG), e.g.
    /// `MECH_HYPRE=rbm=0,variant=1,smooth=0,refine=0,print=1,coarsen=8,agg=1,relax=6,theta_pct=25,interp=6,pmax=4,nodal=4,relax_coarse=9`; `default` otherwise.
    fn knob(name: &str, default: HypreInt) -> HypreInt {
        std::env::var("MECH_HYPRE")
            .ok()
            .and_then(|spec| spec.split(',').find_map(|kv| kv.split_once('=').filter(|(k, _)| *k == name).and_then(|(_, v)| v.parse().ok())))
            .unwrap_or(default)
    }

    /// BoomerAMG with the elasticity options of the module doc and the rotations `rbm` (ParVectors).
    ///
    /// # Safety
    /// `amg` is a fresh BoomerAMG handle; `rbm` holds assembled ParVectors that outlive it.
    unsafe fn configure_amg(amg: Handle, rbm: &mut [Handle]) -> Result<(), SolveError> {
        unsafe {
            ok(HYPRE_BoomerAMGSetPrintLevel(amg, knob("print", 0)), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetCoarsenType(amg, knob("coarsen", 10)), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetAggNumLevels(amg, knob("agg", 0)), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetRelaxType(amg, knob("relax", 8)), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetNumSweeps(amg, 1), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetStrongThreshold(amg, knob("theta_pct", 50) as f64 / 100.0), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetInterpType(amg, knob("interp", 6)), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetPMaxElmts(amg, knob("pmax", 4)), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetMaxLevels(amg, 25), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetMaxIter(amg, 1), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetTol(amg, 0.0), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetNumFunctions(amg, 6), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetNodal(amg, knob("nodal", 4)), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetNodalDiag(amg, 1), "BoomerAMG options")?;
            ok(HYPRE_BoomerAMGSetCycleRelaxType(amg, knob("relax_coarse", 8), 3), "BoomerAMG options")?;
            if !rbm.is_empty() {
                ok(HYPRE_BoomerAMGSetInterpVecVariant(amg, knob("variant", 2)), "BoomerAMG options")?;
                ok(HYPRE_BoomerAMGSetInterpVecQMax(amg, knob("q_max", 4)), "BoomerAMG options")?;
                ok(HYPRE_BoomerAMGSetSmoothInterpVectors(amg, knob("smooth", 1)), "BoomerAMG options")?;
                ok(HYPRE_BoomerAMGSetInterpRefine(amg, knob("refine", 1)), "BoomerAMG options")?;
                ok(HYPRE_BoomerAMGSetInterpVectors(amg, rbm.len() as HypreInt, rbm.as_mut_ptr()), "HYPRE_BoomerAMGSetInterpVectors")?;
            }
        }
        Ok(())
    }

    /// Solves `K dx = r` (full 6n vectors, fixed DOF zero) to `‖r − K dx‖₂ ≤ tol·‖r‖₂` by hypre's
    /// PCG with BoomerAMG; `positions` and `r_scale` give the rigid rotations. `dx` is overwritten.
    pub fn solve(
        op: &FineOp,
        positions: &[Vector3<f64>],
        r_scale: f64,
        r: &[f64],
        dx: &mut [f64],
        tol: f64,
        max_iter: usize,
    ) -> Result<HypreSolve, SolveError> {
        init()?;
        let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let t0 = Instant::now();
        let (node, n_nodes) = nodes(op.fixed);
        let n = 6 * n_nodes;
        if n == 0 {
            dx.iter_mut().for_each(|v| *v = 0.0);
            return Ok(HypreSolve { iterations: 0, assemble_seconds: 0.0, setup_seconds: 0.0, solve_seconds: 0.0 });
        }
        if n > HypreInt::MAX as usize {
            return Err(SolveError::new("hypre", format!("{n} unknowns exceed hypre's 32-bit index range")));
        }
        let (mut sizes, cols, vals) = rows(op, &node);
        let active: Vec<usize> = (0..node.len()).filter(|&i| node[i] != u32::MAX).collect();
        let gather = |full: &[f64]| -> Vec<f64> {
            active.iter().flat_map(|&i| (0..6).map(move |p| if op.fixed[i] & (1 << p) != 0 { 0.0 } else { full[6 * i + p] })).collect()
        };
        // the rigid rotations about the centroid of the nodes (rows of fixed DOF zero)
        let act_pos: Vec<Vector3<f64>> = active.iter().map(|&i| positions[i]).collect();
        let act_fixed: Vec<u8> = active.iter().map(|&i| op.fixed[i]).collect();
        let centre = act_pos.iter().sum::<Vector3<f64>>() / n_nodes as f64;
        let modes = rigid_modes(&act_pos, &act_fixed, &centre, r_scale);
        let mut o = Objects { a: std::ptr::null_mut(), vecs: Vec::new(), amg: std::ptr::null_mut(), pcg: std::ptr::null_mut() };
        let last = (n - 1) as HypreInt;
        let mut par_a: Handle = std::ptr::null_mut();
        // SAFETY: hypre calls on objects created here and destroyed by `o`'s Drop; the row arrays
        // hold `n` rows whose sizes sum to cols.len() == vals.len().
        let (b, (x_ij, x), mut rbm) = unsafe {
            ok(HYPRE_IJMatrixCreate(comm(), 0, last, 0, last, &mut o.a), "HYPRE_IJMatrixCreate")?;
            ok(HYPRE_IJMatrixSetObjectType(o.a, HYPRE_PARCSR), "HYPRE_IJMatrixSetObjectType")?;
            ok(HYPRE_IJMatrixSetRowSizes(o.a, sizes.as_ptr()), "HYPRE_IJMatrixSetRowSizes")?;
            ok(HYPRE_IJMatrixInitialize(o.a), "HYPRE_IJMatrixInitialize")?;
            let row_ids: Vec<HypreInt> = (0..n as HypreInt).collect();
            ok(HYPRE_IJMatrixSetValues(o.a, n as HypreInt, sizes.as_mut_ptr(), row_ids.as_ptr(), cols.as_ptr(), vals.as_ptr()), "HYPRE_IJMatrixSetValues")?;
            ok(HYPRE_IJMatrixAssemble(o.a), "HYPRE_IJMatrixAssemble")?;
            ok(HYPRE_IJMatrixGetObject(o.a, &mut par_a), "HYPRE_IJMatrixGetObject")?;
            let b = vector(&gather(r), &mut o.vecs)?.1;
            let x = vector(&vec![0.0; n], &mut o.vecs)?;
            let mut rbm = Vec::new();
            // off by default: measured 2026-12-08 (docs/coupled.md), the vectors made the hierarchy
            // denser and the solve slower (10⁴ particles: 42 iterations at 0.73 s against 32 at 0.21 s)
            if knob("rbm", 0) != 0 {
                for m in &modes[3..6] {
                    rbm.push(vector(m, &mut o.vecs)?.1);
                }
            }
            (b, x, rbm)
        };
        drop((cols, vals));
        let assemble_seconds = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let (mut its, mut res) = (0, 0.0);
        // SAFETY: as above; BoomerAMG keeps pointers to the interpolation vectors, which `o`
        // destroys only after BoomerAMG.
        let solve_seconds = unsafe {
            ok(HYPRE_BoomerAMGCreate(&mut o.amg), "HYPRE_BoomerAMGCreate")?;
            configure_amg(o.amg, &mut rbm)?;
            ok(HYPRE_ParCSRPCGCreate(comm(), &mut o.pcg), "HYPRE_ParCSRPCGCreate")?;
            ok(HYPRE_ParCSRPCGSetTol(o.pcg, tol), "PCG options")?;
            ok(HYPRE_ParCSRPCGSetMaxIter(o.pcg, max_iter.min(HypreInt::MAX as usize) as HypreInt), "PCG options")?;
            ok(HYPRE_ParCSRPCGSetTwoNorm(o.pcg, 1), "PCG options")?;
            ok(HYPRE_ParCSRPCGSetPrintLevel(o.pcg, 0), "PCG options")?;
            ok(HYPRE_ParCSRPCGSetPrecond(o.pcg, HYPRE_BoomerAMGSolve, HYPRE_BoomerAMGSetup, o.amg), "HYPRE_ParCSRPCGSetPrecond")?;
            let rc = HYPRE_ParCSRPCGSetup(o.pcg, par_a, b, x);
            // hypre 2.26 flags "error in argument 1" (code 12 = HYPRE_ERROR_ARG | 1 << 3) at the end
            // of a BoomerAMG setup with interpolation vectors although the hierarchy is complete
            // (printed with print=1) and PCG converges: cleared; the Newton loop checks the true
            // residual (B10) of the result. Any other code is an error.
            if !(rc == 0 || (rc == 12 && !rbm.is_empty())) {
                ok(rc, "HYPRE_ParCSRPCGSetup (BoomerAMG setup)")?;
            }
            HYPRE_ClearAllErrors();
            let t2 = Instant::now();
            let rc = HYPRE_ParCSRPCGSolve(o.pcg, par_a, b, x);
            let solve = t2.elapsed().as_secs_f64();
            HYPRE_ParCSRPCGGetNumIterations(o.pcg, &mut its);
            HYPRE_ParCSRPCGGetFinalRelativeResidualNorm(o.pcg, &mut res);
            HYPRE_ClearAllErrors();
            if rc != 0 && !(res <= tol) {
                return Err(SolveError {
                    stage: "hypre PCG".into(),
                    message: format!("no convergence to {tol:.1e} in {its} iterations (hypre error {rc}, relative residual {res:.3e})"),
                    residuals: vec![res],
                });
            }
            let mut out = vec![0.0; n];
            let idx: Vec<HypreInt> = (0..n as HypreInt).collect();
            ok(HYPRE_IJVectorGetValues(x_ij, n as HypreInt, idx.as_ptr(), out.as_mut_ptr()), "HYPRE_IJVectorGetValues")?;
            dx.iter_mut().for_each(|v| *v = 0.0);
            for (k, &i) in active.iter().enumerate() {
                for p in 0..6 {
                    if op.fixed[i] & (1 << p) == 0 {
                        dx[6 * i + p] = out[6 * k + p];
                    }
                }
            }
            solve
        };
        let setup_seconds = t1.elapsed().as_secs_f64() - solve_seconds;
        Ok(HypreSolve { iterations: its as usize, assemble_seconds, setup_seconds, solve_seconds })
    }
}

/// The hypre solve itself is tested in tests/hypre.rs (built with the feature).
#[cfg(all(test, not(feature = "hypre")))]
mod tests {
    use crate::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams};

    /// `mechanics.solver = "hypre"` without the feature: a configuration error that names the key,
    /// the value, the allowed values and how to build with it.
    #[test]
    fn hypre_without_the_feature_is_a_clear_error() {
        let p = MechParams { solver: LinearSolver::Hypre, ..Default::default() };
        let msg = BondedSystem::new(2, p, Constraints::none(2)).err().expect("hypre accepted without the feature").to_string();
        for want in ["mechanics.solver = \"hypre\"", "auto, cholesky, cg, amg", "--features h5,hypre", "libhypre-dev"] {
            assert!(msg.contains(want), "{want:?} missing from: {msg}");
        }
    }
}
