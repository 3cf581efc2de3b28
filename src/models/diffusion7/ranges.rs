//! Range table of the 7-DOF model's case-file keys (listed in `crate::kinds::keys::tables`).

use crate::config::ranges::{INF, Range, c, o, p};

/// Keys of `kind = "pair"` cases and of 7-DOF material phases.
pub static RANGES: &[Range] = &[
    // pair geometry and run
    c("pair.radius", 1e-8, 1e-2, "m", "radius R_A of particle A"),
    c("pair.radius_b", 1e-8, 1e-2, "m", "radius R_B of particle B (default: R_A)"),
    c("pair.overlap", 0.0, 0.1, "1", "initial overlap: centre distance (R_A + R_B)(1 - overlap)"),
    c("pair.neck_epsilon", 1e-4, 0.1, "1", "initial neck excess eps of (I2)"),
    o("pair.cone_eta", 0.0, 1.0, "1", "initial cone parameter eta of (I2)"),
    c("pair.end_time", 1e-9, 1e9, "s", "simulated time (default: end of the heating profile; at least 1 ns)"),
    c("load.force", -1e3, 1e3, "N", "pair: constant normal force on the grain boundary, compressive positive (docs/pressure.md)"),
    // temperature history (ramp form; constant, schedule and table are the alternatives)
    c("temperature.constant", 1.0, 1e4, "K", "constant contact temperature"),
    c("temperature.start_temperature", 1.0, 1e4, "K", "ramp: temperature at t = 0 (heating branch truncated below it)"),
    c("temperature.peak_temperature", 1.0, 1e4, "K", "ramp: hold temperature T_max"),
    c("temperature.end_temperature", 1.0, 1e4, "K", "ramp: temperature at the end of cooling"),
    p("temperature.heating_rate", 0.0, 1e4, "K/s", "ramp: heating rate (magnitude)"),
    p("temperature.cooling_rate", 0.0, 1e4, "K/s", "ramp: cooling rate (magnitude)"),
    c("temperature.hold_time", 0.0, 1e8, "s", "ramp: hold time at T_max"),
    // model factors (M6)
    p("model.path_factor_gb", 0.0, 100.0, "1", "lambda_gb: GB path length lambda_gb*a (M6)"),
    p("model.path_factor_neck", 0.0, 100.0, "1", "lambda_n: neck path length lambda_n*s (M6)"),
    p("model.path_factor_cap", 0.0, 100.0, "1", "lambda_p: cap path length lambda_p*s (M6)"),
    c("model.lattice_depth_factor", 0.0, 100.0, "1", "f_l: lattice depth l = f_l*s (M6)"),
    // integrator (T1)
    c(
        "solver.rtol",
        1e-12,
        0.1,
        "1",
        "relative tolerance of the per-contact integrator (T1); at least 1e-12, which double precision can still meet (below it the substeps shrink without end)",
    ),
    p("solver.norm_floor", 0.0, 1.0, "1", "norm floor relative to the smaller radius (T1)"),
    c("solver.max_substep", 1e-12, INF, "s", "largest substep of the per-contact integrator (at least 1 ps, so that every substep advances time)"),
    c("solver.min_step_rel", 0.0, 1e-3, "1", "ModelError if a proposed substep falls below this fraction of the contact age"),
    c("solver.max_substeps", 1.0, 1e12, "1", "ModelError after this many substeps in one interval"),
    // materials of the 7-DOF model (docs/diffusion7.md §9)
    c("materials.*.calibrated_min_temperature", 1.0, 1e4, "K", "lower end of the calibrated temperature range"),
    c("materials.*.calibrated_max_temperature", 1.0, 1e4, "K", "upper end of the calibrated temperature range"),
    p("materials.*.melting_temperature", 1.0, 1e4, "K", "melting (solidus) temperature: a compact run stops when a particle reaches it"),
    c("materials.*.phases.*.from_temperature", 0.0, 1e4, "K", "lowest temperature of the phase"),
    o("materials.*.phases.*.atomic_volume", 0.0, 1e-27, "m^3", "atomic volume Omega"),
    o("materials.*.phases.*.gamma_surface", 0.0, 20.0, "J/m^2", "surface energy gamma_s"),
    c("materials.*.phases.*.gamma_gb", 0.0, 20.0, "J/m^2", "grain-boundary energy gamma_gb"),
    o("materials.*.phases.*.delta_surface", 0.0, 1e-7, "m", "surface-layer thickness delta_s"),
    o("materials.*.phases.*.delta_gb", 0.0, 1e-7, "m", "grain-boundary thickness delta_gb"),
    c("materials.*.phases.*.mobile_fraction_surface", 0.0, 1.0, "1", "fraction of mobile surface atoms n_s"),
    c("materials.*.phases.*.mobile_fraction_gb", 0.0, 1.0, "1", "fraction of mobile GB atoms n_gb"),
    c("materials.*.phases.*.mobile_fraction_lattice", 0.0, 1.0, "1", "lattice weight n_b"),
    c("materials.*.phases.*.d0_surface", 0.0, 1e20, "m^2/s", "surface-diffusion prefactor D0_s"),
    c("materials.*.phases.*.q_surface", 0.0, 2e6, "J/mol", "surface-diffusion activation energy"),
    c("materials.*.phases.*.d0_gb", 0.0, 1e20, "m^2/s", "GB-diffusion prefactor D0_gb"),
    c("materials.*.phases.*.q_gb", 0.0, 2e6, "J/mol", "GB-diffusion activation energy"),
    c("materials.*.phases.*.d0_lattice", 0.0, 1e20, "m^2/s", "lattice-diffusion prefactor D0_b"),
    c("materials.*.phases.*.q_lattice", 0.0, 2e6, "J/mol", "lattice-diffusion activation energy"),
];
