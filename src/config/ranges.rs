//! Range tables: the mechanism ([`Range`], [`check_in`], [`lookup_in`]) and the shared table of
//! the keys every kind reads ([`TABLE`]: time, output, materials, particles, thermal, …). A module
//! with keys of its own keeps its table beside its code and checks against it with [`check_in`];
//! the list of every table is `crate::kinds::keys::tables`.
//! Keys are written as in the case file with array/table indices replaced by `*`
//! (e.g. `materials.*.density`). `docs/case-file.md` is checked against this table by a test.

use crate::error::ConfigError;

/// An allowed interval. `lo_open`/`hi_open` make an end exclusive.
#[derive(Debug, Clone, Copy)]
pub struct Range {
    pub key: &'static str,
    pub lo: f64,
    pub hi: f64,
    pub lo_open: bool,
    pub hi_open: bool,
    pub unit: &'static str,
    pub meaning: &'static str,
}

impl Range {
    pub fn contains(&self, v: f64) -> bool {
        if !v.is_finite() && !(v.is_infinite() && v > 0.0 && self.hi.is_infinite()) {
            return false;
        }
        let lo_ok = if self.lo_open { v > self.lo } else { v >= self.lo };
        let hi_ok = if self.hi_open { v < self.hi } else { v <= self.hi };
        lo_ok && hi_ok
    }

    pub fn describe(&self) -> String {
        let fmt = |x: f64| if x.is_infinite() { "inf".to_string() } else { crate::error::fmt_value(x) };
        format!("{}{}, {}{}", if self.lo_open { "(" } else { "[" }, fmt(self.lo), fmt(self.hi), if self.hi_open { ")" } else { "]" })
    }

    pub fn check(&self, key: &str, v: f64) -> Result<f64, ConfigError> {
        if self.contains(v) {
            Ok(v)
        } else {
            Err(ConfigError::OutOfRange { key: key.to_string(), value: v, range: self.describe(), unit: self.unit.to_string() })
        }
    }
}

/// +∞ for open-ended ranges.
pub const INF: f64 = f64::INFINITY;

/// `[lo, hi]` closed.
pub const fn c(key: &'static str, lo: f64, hi: f64, unit: &'static str, meaning: &'static str) -> Range {
    Range { key, lo, hi, lo_open: false, hi_open: false, unit, meaning }
}
/// `(lo, hi]`: strictly positive quantities.
pub const fn p(key: &'static str, lo: f64, hi: f64, unit: &'static str, meaning: &'static str) -> Range {
    Range { key, lo, hi, lo_open: true, hi_open: false, unit, meaning }
}

/// `(lo, hi)` open.
pub const fn o(key: &'static str, lo: f64, hi: f64, unit: &'static str, meaning: &'static str) -> Range {
    Range { key, lo, hi, lo_open: true, hi_open: true, unit, meaning }
}

/// The table. Add a row for every new numeric key.
pub static TABLE: &[Range] = &[
    // time stepping
    c(
        "time.end",
        1e-9,
        1e9,
        "s",
        "simulated end time (default: the end of the heating profile(s); below 1 ns nothing sinters or heats: a floor, so that no loop runs on subnormal times)",
    ),
    c("time.dt", 1e-15, 1e7, "s", "time step (initial step where adaptive); end/dt at most 1e9 steps"),
    c("time.dt_min", 1e-15, 1e7, "s", "smallest step the step control may take (at most dt_max)"),
    c("time.dt_max", 1e-15, 1e7, "s", "largest step the step control may take; end/dt_max at most 1e9 steps"),
    c("time.strategy", 1.0, 2.0, "1", "step control: 1 global, 2 per-contact subdivision"),
    c("time.alpha", 1.01, 10.0, "1", "step growth/shrink factor alpha (docs/coupled.md (S4): below 1.58 for 4th-order pairs)"),
    c("time.grow_below", 0.0, 1.0, "1", "strategy 2: grow when fewer contacts than this fraction subdivided"),
    c("time.substeps_allowed", 1.0, 1e6, "1", "strategy 2: a contact needing more substeps than this counts as subdivided"),
    p("time.stop_relative_density", 0.0, 1.0, "1", "compact runs: stop once the relative density (eq. 49) reaches this value"),
    c("time.heat_tolerance", 1e-9, 1e4, "K", "local error tolerance of the heat step (heat-model.md eq. E3); absent: fixed dt"),
    c("time.shrink_above", 0.0, 1.0, "1", "strategy 2: shrink when more contacts than this fraction subdivided"),
    // output
    c("output.snapshots", 0.0, 1e5, "1", "number of VTU/HDF5 snapshots, evenly spaced in time"),
    c("output.series_every", 1.0, 1e9, "1", "write a series row every this many steps"),
    c("output.checkpoint_every", 0.0, 1e9, "1", "write a checkpoint every this many steps (0: never)"),
    c("output.conductivity_at.*", 0.0, 1e9, "s", "times of the effective-conductivity analyses of a compact run"),
    c("output.correction_histogram_at.*", 0.0, 1e9, "s", "times of the y4/y7 correction histograms of a compact run"),
    // contacts and mechanics of compact runs
    c("contacts.detect_every", 1.0, 1e9, "1", "neighbour search every this many steps"),
    c("contacts.gap_tolerance", 0.0, 0.1, "1", "surface gap, relative to the mean radius, below which a pair counts as touching"),
    c("contacts.new_contact_gap", 0.0, 0.1, "1", "gap_tolerance of the searches after the start (default: gap_tolerance; 0: overlapping pairs only)"),
    c("contacts.epsilon", 1e-4, 0.1, "1", "initial neck excess epsilon of a new contact (I2)"),
    o("contacts.eta", 0.0, 1.0, "1", "initial cone parameter eta of a new contact (I2)"),
    c("mechanics.rtol", 1e-15, 1e-2, "1", "Newton tolerance of the bonded solve: scaled residual relative to the scaled load"),
    c("mechanics.warm_start_depth", 1.0, 8.0, "1", "earlier solutions spanning the warm start of the bonded solve (an integer)"),
    c(
        "mechanics.update_rank",
        0.0,
        2000.0,
        "1",
        "largest rank of the low-rank update of the kept Cholesky factor for new bonds (an integer; default 90; 0: off)",
    ),
    c("mechanics.plane_margin", 1.0, 2.0, "1", "a particle touches a principal plane when its centre is within margin * r"),
    c(
        "mechanics.sliding_factor",
        1e-3,
        10.0,
        "1",
        "sliding = \"viscous\": factor f of the tangential neck viscosity f (R*/a)^2 / M_c, M_c the contact's normal mobility (docs/mechanics.md (B24); default 0.03, docs/decisions-mechanics.md \"Sliding\")",
    ),
    c("load.stress", 0.0, 1e9, "Pa", "compact runs: applied compressive stress (also every stress of load.stress_table; docs/pressure.md)"),
    p(
        "load.contact_stress_limit",
        0.0,
        1e11,
        "Pa",
        "compact runs: largest mean normal stress F_n/(pi a^2) a contact passes to its diffusion model (docs/pressure.md (P5))",
    ),
    c("load.stress_table.time", 0.0, 1e9, "s", "compact runs: times of the load.stress_table rows, strictly increasing"),
    // materials
    p("materials.*.density", 0.0, 1e5, "kg/m^3", "mass density rho"),
    p("materials.*.heat_capacity", 0.0, 1e5, "J/(kg K)", "specific heat capacity c"),
    p("materials.*.conductivity", 0.0, 1e4, "W/(m K)", "thermal conductivity kappa"),
    p(
        "materials.*.electrical_resistivity",
        0.0,
        1e16,
        "ohm m",
        "electrical resistivity rho_e of `sinterdem conductivity` with conductivity.quantity = \"electrical\"",
    ),
    p("materials.*.young_modulus", 0.0, 1e13, "Pa", "Young's modulus E"),
    c("materials.*.poisson_ratio", -0.99, 0.4999, "1", "Poisson's ratio nu"),
    c("materials.*.emissivity", 0.0, 1.0, "1", "total hemispherical emissivity"),
    c(
        "materials.*.thermal_expansion",
        0.0,
        1e-3,
        "1/K",
        "compact runs: linear thermal expansion coefficient alpha of the particle radii (0: off; docs/coupled.md (X1))",
    ),
    // particles
    c("particles.radius", 1e-9, 1.0, "m", "particle radius (also every radius of a packing file)"),
    c("particles.radius_2", 1e-9, 1.0, "m", "second particle radius of a pair"),
    c("particles.position", -1e3, 1e3, "m", "packing file: every centre coordinate x, y, z"),
    p("particles.periodic_box", 0.0, 1e3, "m", "periodic box [Lx, Ly, Lz] of a file packing, from the origin; each at least two largest particle diameters"),
    c("particles.overlap", 0.0, 0.6, "1", "initial overlap h relative to the smaller radius"),
    c("particles.initial_temperature", 1.0, 1e4, "K", "initial temperature of every particle"),
    // thermal
    p("thermal.conductance_factor", 0.0, 100.0, "1", "c_K of K_i = c_K kappa pi a (docs/heat-model.md (H6))"),
    p("thermal.contact_conductance", 0.0, INF, "W/K", "interface conductance K_c in series (eq. 8)"),
    c(
        "thermal.boundary_resistance",
        0.0,
        1.0,
        "m^2 K/W",
        "interface (Kapitza / grain-boundary) resistance per unit neck area R_b, R_b/(pi a^2) in series with each pipe (docs/heat-model.md (H7))",
    ),
    c("thermal.furnace.convection_coefficient", 0.0, 1e6, "W/(m^2 K)", "convective heat transfer coefficient h_c"),
    c("thermal.furnace.emissivity", 0.0, 1.0, "1", "emissivity used for radiation to the furnace walls"),
    c("thermal.furnace.exposure", 0.0, 1.0, "1", "fraction of an exposed particle's sphere area facing the furnace"),
    c("thermal.radiation_tolerance", 1e-15, 1e-3, "1", "radiation Newton stop: max|dT| <= tol * max T"),
    c("thermal.gap.gas_conductivity", 0.0, 1.0, "W/(m K)", "gas conductivity k_g of the gap model (docs/heat-model.md (H18)); 0: vacuum"),
    p("thermal.gap.layer_thickness", 0.0, 1.0, "1", "gap model: pairs with surface gap up to this fraction of the larger radius exchange heat (H19)"),
    c("thermal.gap.jump_distance", 0.0, 1e-3, "m", "gap model: temperature-jump distance M of the rarefied gas, both surfaces (H18)"),
    c("thermal.gap.emissivity", 0.0, 1.0, "1", "gap model: surface emissivity for radiation across the gap (H22); 0: off"),
    c("thermal.volumetric.*.power_density", -1e15, 1e15, "W/m^3", "volumetric heat generation q'''"),
    c("conductivity.temperature_difference", 1e-6, 1e4, "K", "T_hot - T_cold of the effective-conductivity solve"),
    c("conductivity.layer_fraction", 0.0, 0.5, "1", "thickness of each Dirichlet layer as a fraction of the extent"),
];

/// Looks up `key` in `tables`, matching `*` against any one path segment.
pub fn lookup_in(tables: &[&'static [Range]], key: &str) -> Option<&'static Range> {
    tables.iter().flat_map(|t| t.iter()).find(|r| pattern_matches(r.key, key))
}

/// Looks up `key` among the shared keys of this module's [`TABLE`] (time, output, materials, …).
pub fn lookup(key: &str) -> Option<&'static Range> {
    lookup_in(&[TABLE], key)
}

/// Checks `value` of `key` against a module's own range table `own`, then the shared [`TABLE`].
/// A key found in neither is an internal error (the module forgot a row).
pub fn check_in(own: &'static [Range], key: &str, value: f64) -> Result<f64, ConfigError> {
    let r = lookup_in(&[own, TABLE], key).ok_or_else(|| ConfigError::invalid(format!("internal: key {key} has no entry in the range table")))?;
    r.check(key, value)
}

fn pattern_matches(pattern: &str, key: &str) -> bool {
    let mut p = pattern.split('.');
    let mut k = key.split('.');
    loop {
        match (p.next(), k.next()) {
            (None, None) => return true,
            (Some(a), Some(b)) if a == "*" || a == b => continue,
            _ => return false,
        }
    }
}

/// `tables` as a Markdown table (key, allowed range, unit, meaning), for `docs/case-file.md`
/// (`sinterdem keys` prints every table of the crate, `crate::calibrate::every_table`; a test keeps the
/// document in step).
pub fn markdown(tables: &[&[Range]]) -> String {
    let mut s = String::from("| key | allowed | unit | meaning |\n|---|---|---|---|\n");
    for r in tables.iter().flat_map(|t| t.iter()) {
        s.push_str(&format!("| `{}` | {} | {} | {} |\n", r.key, r.describe(), r.unit, r.meaning));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn lookup_matches_wildcards_and_reports_range() {
        let r = lookup("materials.copper.density").unwrap();
        assert_eq!(r.unit, "kg/m^3");
        let e = r.check("materials.copper.density", -1.0).unwrap_err().to_string();
        assert!(e.contains("materials.copper.density") && e.contains("(0, 100000]") && e.contains("kg/m^3"), "{e}");
        assert!(lookup("materials.copper").is_none());
        assert!(r.check("x", f64::NAN).is_err());
    }
    #[test]
    fn keys_are_unique() {
        let all: Vec<&Range> = TABLE.iter().collect();
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a.key, b.key);
            }
        }
    }
}
