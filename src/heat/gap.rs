//! Heat across the gaps between near, non-touching particles (docs/heat-model.md "Heat across
//! gaps", (H18)–(H23)): conduction through the furnace gas and, optionally, radiation between the
//! facing surfaces.
//!
//! Both use the flux-tube picture of the surrounding-layer model (Rong & Horio 1999; as in Cheng,
//! Yu & Zulli 1999 and Zhou, Yu & Zulli 2009 with the particles isothermal): the heat between two
//! spheres runs along tubes parallel to the line of centres, a tube at distance r from that line
//! crossing the gas over the local gap δ(r). Only tubes inside a gas layer of thickness f·R_L
//! around the larger sphere (radius R_L) count, so a pair conducts while its surface gap
//! s = d − r_i − r_j lies in (0, f·R_L], and its conductance falls continuously to zero at
//! s = f·R_L. Touching pairs are contacts (the neck pipes (H6)–(H8)); the gap model never adds to
//! them.

use crate::error::{ConfigError, SolveError};
use crate::heat::{HeatNetwork, PipeConductance};
use crate::units::STEFAN_BOLTZMANN;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// `[thermal.gap]`: conduction through the gas, and radiation, between particles that are near but
/// not in contact (docs/heat-model.md "Heat across gaps").
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GapSpec {
    /// Thermal conductivity of the furnace gas k_g [W/(m·K)] (default 0: vacuum, no gas conduction).
    #[serde(default)]
    pub gas_conductivity: f64,
    /// Gas-layer thickness f relative to the larger radius of a pair [1]: pairs with surface gap
    /// `0 < s ≤ f·max(r_i, r_j)` exchange heat (default 0.2; (H19)).
    #[serde(default = "gap_layer")]
    pub layer_thickness: f64,
    /// Temperature-jump distance M of the rarefied gas, both surfaces together [m] (default 0:
    /// continuum gas; (H18)).
    #[serde(default)]
    pub jump_distance: f64,
    /// Emissivity ε of the particle surfaces for radiation across the gap [1] (default 0: no
    /// radiation; (H22)).
    #[serde(default)]
    pub emissivity: f64,
}

fn gap_layer() -> f64 {
    0.2
}

/// The gap model of a case (`[thermal.gap]`), validated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapModel {
    /// Gas conductivity k_g [W/(m·K)] (0: vacuum).
    pub gas_conductivity: f64,
    /// Gas-layer thickness f relative to the larger radius of a pair [1] (H19).
    pub layer_thickness: f64,
    /// Temperature-jump distance M of the rarefied gas, both surfaces together [m] (H18).
    pub jump_distance: f64,
    /// Surface emissivity ε for radiation across the gap [1] (0: no radiation; (H22)).
    pub emissivity: f64,
}

impl GapModel {
    /// The model of `[thermal.gap]`, range-checked (key, value, range and unit in the error);
    /// `None` when it transfers nothing (k_g = 0 and ε = 0).
    pub fn from_spec(spec: &GapSpec) -> Result<Option<GapModel>, ConfigError> {
        let m = GapModel {
            gas_conductivity: crate::config::check("thermal.gap.gas_conductivity", spec.gas_conductivity)?,
            layer_thickness: crate::config::check("thermal.gap.layer_thickness", spec.layer_thickness)?,
            jump_distance: crate::config::check("thermal.gap.jump_distance", spec.jump_distance)?,
            emissivity: crate::config::check("thermal.gap.emissivity", spec.emissivity)?,
        };
        Ok((m.gas_conductivity > 0.0 || m.emissivity > 0.0).then_some(m))
    }

    /// Gas conductance (H18) and radiation coefficient (H22) of a pair of radii `r_i`, `r_j` [m]
    /// at centre distance `d` [m]: `Some((G_g [W/K], c [W/K⁴]))` when its surface gap lies in
    /// (0, f·max(r_i, r_j)], else `None`.
    pub fn pair(&self, r_i: f64, r_j: f64, d: f64) -> Option<(f64, f64)> {
        let r_out = outer_radius(r_i, r_j, d, self.layer_thickness)?;
        let g = if self.gas_conductivity > 0.0 { gas_conductance(self.gas_conductivity, r_i, r_j, d, r_out, self.jump_distance) } else { 0.0 };
        Some((g, radiation_coefficient(self.emissivity, r_out)))
    }
}

/// (H19) Radius r_out [m] of the disc of flux tubes between spheres of radii `r_i`, `r_j` [m] at
/// centre distance `d` [m]: where the gas layer of radius (1 + f)·R_L around the larger sphere
/// meets the surface of the smaller one (the whole smaller radius when the layer reaches past its
/// equator). `None` unless the surface gap s = d − r_i − r_j lies in (0, f·R_L].
pub fn outer_radius(r_i: f64, r_j: f64, d: f64, layer: f64) -> Option<f64> {
    let (rl, rs) = (r_i.max(r_j), r_i.min(r_j));
    let s = d - rl - rs;
    if !(s > 0.0 && s <= layer * rl) {
        return None;
    }
    let lens = (1.0 + layer) * rl;
    // axial distance from the smaller sphere's centre (towards the larger one) of the circle
    // where the layer meets the smaller sphere
    let y = ((d - lens) * (d + lens) + rs * rs) / (2.0 * d);
    if y <= 0.0 {
        return Some(rs);
    }
    Some(((rs - y) * (rs + y)).max(0.0).sqrt())
}

/// `R − √(R² − r²)` [m], written without cancellation: the depth of a sphere of radius `radius`
/// below its tangent plane at distance `r` from the axis.
fn sag(radius: f64, r2: f64) -> f64 {
    r2 / (radius + (radius * radius - r2).max(0.0).sqrt())
}

/// (H18) Gas conductance [W/K] between isothermal spheres of radii `r_i`, `r_j` [m] at centre
/// distance `d` [m] (surface gap s = d − r_i − r_j > 0) through the flux tubes r ≤ `r_out` [m]:
/// `G_g = k_g ∫_0^{r_out} 2πr dr / (δ(r) + M)`, `δ(r) = s + (r_i − √(r_i² − r²)) + (r_j − √(r_j² − r²))`,
/// `k_g` [W/(m·K)], `jump` M [m] the temperature-jump distance. Evaluated as
/// `π k_g R′ ∫_0^V q(v) dv` with `1/R′ = (1/r_i + 1/r_j)/2`, `v = ln(1 + r²/(R′u))`, `u = s + M`,
/// `q = (u + r²/R′)/(δ + M) ≤ 1` (q = 1 is the parabolic gap, whose integral is the logarithm
/// (H21)), by adaptive Gauss–Kronrod quadrature to a relative 1e-12.
pub fn gas_conductance(k_g: f64, r_i: f64, r_j: f64, d: f64, r_out: f64, jump: f64) -> f64 {
    let s = d - r_i - r_j;
    let u = s + jump;
    if !(u > 0.0 && r_out > 0.0 && k_g > 0.0) {
        return 0.0;
    }
    let kap = 0.5 * (1.0 / r_i + 1.0 / r_j); // 1/R′
    let q = |v: f64| -> f64 {
        let r2 = u * v.exp_m1() / kap;
        let par = u + kap * r2;
        par / (u + sag(r_i, r2) + sag(r_j, r2))
    };
    let v_end = (kap * r_out * r_out / u).ln_1p();
    PI * k_g / kap * integrate(q, 0.0, v_end, 1e-12)
}

/// (H20) Closed form of (H18) for equal radii `r` [m] (Bahrami, Yovanovich & Culham 2006, the
/// macrogap resistance R_G): `G_g = (π k_g/2)[S ln((S − B)/(S − A)) + B − A]`, `S = d + M`,
/// `A = 2r`, `B = 2√(r² − r_out²)`; written without cancellation. For tests and checks.
pub fn gas_conductance_equal(k_g: f64, r: f64, d: f64, r_out: f64, jump: f64) -> f64 {
    let u = d - 2.0 * r + jump; // S − A
    let b_minus_a = -2.0 * sag(r, r_out * r_out);
    0.5 * PI * k_g * ((d + jump) * (-b_minus_a / u).ln_1p() + b_minus_a)
}

/// (H22) Radiation coefficient c [W/K⁴] of a pair whose flux-tube disc has radius `r_out` [m]:
/// each tube is a gap between two grey parallel surfaces of emissivity `eps`,
/// `c = σ π r_out² / (2/ε − 1)`; the exchange is `c (T_j⁴ − T_i⁴)`. 0 for ε = 0.
pub fn radiation_coefficient(eps: f64, r_out: f64) -> f64 {
    if !(eps > 0.0) {
        return 0.0;
    }
    STEFAN_BOLTZMANN * PI * r_out * r_out / (2.0 / eps - 1.0)
}

/// (H23) Exact secant conductance [W/K] of the radiative exchange `c (T_j⁴ − T_i⁴)` between
/// temperatures `ti`, `tj` [K]: `c (T_i² + T_j²)(T_i + T_j)`, so that `G (T_j − T_i)` equals the
/// exchange exactly.
pub fn radiative_conductance(c: f64, ti: f64, tj: f64) -> f64 {
    c * (ti * ti + tj * tj) * (ti + tj)
}

// Gauss–Kronrod 7–15 nodes and weights on [−1, 1] (Piessens et al. 1983, QUADPACK qk15).
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_18,
    0.140_653_259_715_525_92,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_83,
];
const WG: [f64; 4] = [0.129_484_966_168_869_7, 0.279_705_391_489_276_7, 0.381_830_050_505_118_9, 0.417_959_183_673_469_4];

/// Kronrod estimate and |Kronrod − Gauss| of ∫_a^b f.
fn gk15(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> (f64, f64) {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let fc = f(c);
    let (mut k, mut g) = (WGK[7] * fc, WG[3] * fc);
    for i in 0..7 {
        let s = f(c - h * XGK[i]) + f(c + h * XGK[i]);
        k += WGK[i] * s;
        if i % 2 == 1 {
            g += WG[i / 2] * s;
        }
    }
    (k * h, ((k - g) * h).abs())
}

/// Adaptive Gauss–Kronrod quadrature of `f` over [a, b] to a relative tolerance `rel` of the
/// integral of |f| (the integrands here are positive). Intervals are bisected until each error
/// estimate is below its share of the tolerance (at most 2000 intervals).
pub fn integrate(f: impl Fn(f64) -> f64, a: f64, b: f64, rel: f64) -> f64 {
    if !(b > a) {
        return 0.0;
    }
    let (whole, err) = gk15(&f, a, b);
    if err <= rel * whole.abs() {
        return whole;
    }
    let mut parts = vec![(a, b, whole, err)];
    for _ in 0..2000 {
        let total: f64 = parts.iter().map(|p| p.2).sum();
        let errs: f64 = parts.iter().map(|p| p.3).sum();
        if errs <= rel * total.abs() {
            break;
        }
        // bisect the interval with the largest error
        let k = parts.iter().enumerate().max_by(|x, y| x.1.3.total_cmp(&y.1.3)).map(|(k, _)| k).unwrap_or(0);
        let (lo, hi, _, _) = parts.swap_remove(k);
        let mid = 0.5 * (lo + hi);
        let (l, el) = gk15(&f, lo, mid);
        let (r, er) = gk15(&f, mid, hi);
        parts.push((lo, mid, l, el));
        parts.push((mid, hi, r, er));
    }
    // sum in order of position, so that the result does not depend on the bisection order
    parts.sort_by(|x, y| x.0.total_cmp(&y.0));
    parts.iter().map(|p| p.2).sum()
}

/// The gap pipes at one configuration: pairs `(i, j)`, i < j, sorted, not in contact.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GapPipes {
    pub pairs: Vec<[u32; 2]>,
    /// Surface gap s = d − r_i − r_j [m].
    pub gap: Vec<f64>,
    /// Gas conductance G_g (H18) [W/K].
    pub gas: Vec<f64>,
    /// Radiation coefficient c (H22) [W/K⁴] (all 0 without radiation).
    pub radiation: Vec<f64>,
}

impl GapPipes {
    pub fn len(&self) -> usize {
        self.pairs.len()
    }
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
    /// The gas pipes as network pipes: halves 2G_g (the gas split at the mid-gap), pipe G_g [W/K].
    pub fn parts(&self) -> impl Iterator<Item = PipeConductance> + '_ {
        self.gas.iter().map(|&g| PipeConductance { half_i: 2.0 * g, half_j: 2.0 * g, pair: g, boundary: 0.0 })
    }
}

/// The gap model with its neighbour search: a Verlet list of candidate pairs from the contact
/// detection's cell list ([`crate::contacts::detect::touching_pairs`]) with margin 2f·r_max,
/// searched again only when some particle has moved (or grown) by half the skin f·r_max since the
/// last search. Every call of [`update`](Self::update) filters the candidates at the current
/// positions, so the gap pipes depend on the configuration only, not on when the list was built
/// (a resumed run finds the same pipes).
#[derive(Debug, Clone)]
pub struct GapNetwork {
    pub model: GapModel,
    candidates: Vec<[u32; 2]>,
    reference: Vec<Vector3<f64>>,
    reference_radius: Vec<f64>,
    skin: f64,
    contacts: std::collections::HashSet<[u32; 2]>,
    contacts_seen: Vec<[u32; 2]>,
    current: Option<GapPipes>,
    /// Candidate searches so far [1].
    pub searches: u64,
}

impl GapNetwork {
    pub fn new(model: GapModel) -> Self {
        GapNetwork {
            model,
            candidates: Vec::new(),
            reference: Vec::new(),
            reference_radius: Vec::new(),
            skin: 0.0,
            contacts: Default::default(),
            contacts_seen: Vec::new(),
            current: None,
            searches: 0,
        }
    }

    /// The gap pipes of the last [`update`](Self::update), if any.
    pub fn pipes(&self) -> Option<&GapPipes> {
        self.current.as_ref()
    }

    fn search(&mut self, position: &[Vector3<f64>], radius: &[f64]) {
        let r_max = radius.iter().copied().fold(0.0, f64::max);
        self.skin = self.model.layer_thickness * r_max;
        self.candidates = crate::contacts::detect::touching_pairs(position, radius, 2.0 * self.skin).into_iter().map(|(i, j)| [i, j]).collect();
        self.reference = position.to_vec();
        self.reference_radius = radius.to_vec();
        self.searches += 1;
    }

    fn stale(&self, position: &[Vector3<f64>], radius: &[f64]) -> bool {
        if self.reference.len() != position.len() || self.searches == 0 {
            return true;
        }
        let half = 0.5 * self.skin;
        position
            .iter()
            .zip(&self.reference)
            .zip(radius.iter().zip(&self.reference_radius))
            .any(|((x, x0), (r, r0))| (x - x0).norm() + (r - r0).max(0.0) >= half)
    }

    /// The gap pipes at `position`, `radius` [m]: the candidate pairs whose surface gap lies in
    /// (0, f·R_L] and that are not among `contacts` (pairs i < j), with their conductances.
    pub fn update(&mut self, position: &[Vector3<f64>], radius: &[f64], contacts: &[[u32; 2]]) -> &GapPipes {
        if self.stale(position, radius) {
            self.search(position, radius);
        }
        // the contact set grows by appending (compact runs); anything else rebuilds it
        let seen = self.contacts_seen.len();
        if contacts.len() < seen || contacts[..seen] != self.contacts_seen[..] {
            self.contacts.clear();
            self.contacts_seen.clear();
        }
        let seen = self.contacts_seen.len();
        self.contacts.extend(contacts[seen..].iter().map(|&[i, j]| [i.min(j), i.max(j)]));
        self.contacts_seen.extend_from_slice(&contacts[seen..]);
        let model = self.model;
        let contacts = &self.contacts;
        let eval = |&[i, j]: &[u32; 2]| -> Option<([u32; 2], f64, f64, f64)> {
            if contacts.contains(&[i, j]) {
                return None;
            }
            let (ri, rj) = (radius[i as usize], radius[j as usize]);
            let d = (position[j as usize] - position[i as usize]).norm();
            let (g, c) = model.pair(ri, rj, d)?;
            Some(([i, j], d - ri - rj, g, c))
        };
        let found: Vec<([u32; 2], f64, f64, f64)> = if self.candidates.len() > 4096 {
            self.candidates.par_iter().filter_map(eval).collect()
        } else {
            self.candidates.iter().filter_map(eval).collect()
        };
        let mut out = GapPipes::default();
        for (p, s, g, c) in found {
            out.pairs.push(p);
            out.gap.push(s);
            out.gas.push(g);
            out.radiation.push(c);
        }
        self.current = Some(out);
        self.current.as_ref().unwrap()
    }

    /// The gap pairs at `position`, `radius` [m] besides `contacts`: those of the last
    /// [`update`](Self::update), or (before the first) a fresh search.
    pub fn pairs_now(&self, position: &[Vector3<f64>], radius: &[f64], contacts: &[[u32; 2]]) -> Vec<[u32; 2]> {
        match &self.current {
            Some(p) => p.pairs.clone(),
            None => {
                let mut fresh = GapNetwork::new(self.model);
                fresh.update(position, radius, contacts).pairs.clone()
            }
        }
    }
}

/// Sets the topology of `net` to the contact pipes `contacts` and, with a gap model, the gap pipes
/// of the current `position`, `radius` [m] after them (with their radiation coefficients), and
/// returns the conductances of all pipes: `parts` (one per contact) followed by the gap pipes'
/// gas conductances. Without a gap model this is `net.set_topology(contacts)` and `parts`
/// unchanged. Also returns the symbolic-analysis time [s].
pub fn attach(
    net: &mut HeatNetwork,
    gap: Option<&mut GapNetwork>,
    position: &[Vector3<f64>],
    radius: &[f64],
    contacts: &[[u32; 2]],
    parts: Vec<PipeConductance>,
) -> Result<(Vec<PipeConductance>, f64), SolveError> {
    let Some(gap) = gap else {
        let secs = net.set_topology(contacts)?;
        return Ok((parts, secs));
    };
    let gp = gap.update(position, radius, contacts);
    let secs = net.set_topology_with_gaps(contacts, &gp.pairs)?;
    net.set_gap_radiation(&gp.radiation)?;
    let mut all = parts;
    all.extend(gp.parts());
    Ok((all, secs))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kronrod_rule_integrates_polynomials_exactly() {
        // weights sum to 2 on [−1, 1]; K15 is exact to degree 22, G7 to degree 13
        let (k, e) = gk15(&|x: f64| x.powi(12) + 3.0 * x.powi(4) + 1.0, -1.0, 1.0);
        let exact = 2.0 / 13.0 + 6.0 / 5.0 + 2.0;
        assert!((k - exact).abs() < 1e-15, "{k} {exact}");
        assert!(e < 1e-14, "{e}");
        let (k, _) = gk15(&|x: f64| x.powi(22), -1.0, 1.0);
        assert!((k - 2.0 / 23.0).abs() < 1e-15);
        // adaptive: ∫_0^1 √x = 2/3 (a derivative singularity at 0)
        let v = integrate(|x: f64| x.sqrt(), 0.0, 1.0, 1e-12);
        assert!((v - 2.0 / 3.0).abs() < 1e-11, "{v}");
    }

    #[test]
    fn outer_radius_is_continuous_at_the_layer_edge_and_capped_by_the_smaller_radius() {
        let r = 1.0;
        // at s = f R the layer just reaches the other sphere (values exact in binary)
        assert_eq!(outer_radius(r, r, 2.25, 0.25), Some(0.0));
        assert!(outer_radius(r, r, 2.25 * (1.0 + 1e-15), 0.25).is_none());
        assert!(outer_radius(r, r, 2.0, 0.2).is_none());
        // equal spheres nearly touching: law of cosines, lens radius 1.2, distance 2
        let ro = outer_radius(r, r, 2.0 + 1e-12, 0.2).unwrap();
        let cosb = (1.44f64 - 1.0 + 4.0) / (2.0 * 1.2 * 2.0);
        assert!((ro - 1.2 * (1.0 - cosb * cosb).sqrt()).abs() < 1e-9, "{ro}");
        // a small sphere wholly inside the layer of a large one: the whole smaller radius
        assert_eq!(outer_radius(0.1, 1.0, 1.2, 1.0), Some(0.1));
    }
}
