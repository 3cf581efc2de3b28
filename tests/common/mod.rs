//! Helpers shared by the integration tests (`mod common;` in each test file): temporary
//! directories, the relative error, configuration-error keys, documentation snippets, blocks of the
//! bundled green copper packing and the copper-compact case text.
#![allow(dead_code)]

use nalgebra::Vector3;
use sinterdem::contacts::detect::touching_pairs_periodic;
use sinterdem::error::ConfigError;
use std::path::{Path, PathBuf};

/// Relative difference |a − b| / |b| [1].
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

/// The key a configuration error names (or its message when it names none).
pub fn key_of(e: &ConfigError) -> String {
    match e {
        ConfigError::OutOfRange { key, .. } | ConfigError::Inconsistent { key, .. } => key.clone(),
        ConfigError::Invalid(m) => m.clone(),
    }
}

/// The `[section]` tables of the TOML code blocks of the document `doc`, in order.
pub fn doc_snippets(doc: &str, section: &str) -> Vec<toml::Value> {
    let text = std::fs::read_to_string(doc).unwrap();
    let mut out = Vec::new();
    let mut rest = text.as_str();
    while let Some(i) = rest.find("```toml\n") {
        let body = &rest[i + 8..];
        let j = body.find("```").unwrap();
        let t: toml::Table = body[..j].parse().unwrap();
        if let Some(v) = t.get(section) {
            out.push(v.clone());
        }
        rest = &body[j + 3..];
    }
    out
}

/// A fresh, empty directory `sinterdem-{prefix}-{name}-{pid}` under the system temp dir.
pub fn fresh_dir(prefix: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sinterdem-{prefix}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A fresh, empty directory `sinterdem-{test}-{name}-{pid}` for the test binary `test` (the
/// test file's name, so test binaries running side by side cannot collide); within a file each
/// test passes its own `name`.
pub fn tmp_dir(name: &str) -> PathBuf {
    fresh_dir(env!("CARGO_CRATE_NAME"), name)
}

/// A fresh, empty directory per call, `sinterdem-{test}-{name}-{k}-{pid}` with `k` a call counter:
/// for helpers that several tests, running in parallel, call with the same `name` (else one test
/// removes another's files).
pub fn tmp_dir_per_call(name: &str) -> PathBuf {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    tmp_dir(&format!("{name}-{k}"))
}

/// The data lines of the bundled green copper packing (`cases/data/green-copper.csv`, columns
/// x, y, z, r [m]) whose centre has x, y below `edge` and z below `height` [m], with the values.
pub fn green_copper_block(edge: f64, height: f64) -> Vec<(String, [f64; 4])> {
    let text = std::fs::read_to_string("cases/data/green-copper.csv").unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('x'))
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
            (line.to_string(), [v[0], v[1], v[2], v[3]])
        })
        .filter(|(_, v)| v[0] < edge && v[1] < edge && v[2] < height)
        .collect()
}

/// Writes `header` and the `lines` of a packing block to `dir/file`; returns the path.
pub fn write_block(dir: &Path, file: &str, header: &str, lines: impl IntoIterator<Item = String>) -> PathBuf {
    let mut out = format!("{header}\n");
    for l in lines {
        out.push_str(&l);
        out.push('\n');
    }
    let path = dir.join(file);
    std::fs::write(&path, out).unwrap();
    path
}

/// The `[[materials]]` body of the bundled copper preset.
pub const COPPER: &str = "name = \"copper\"\npreset = \"copper-ivannikov2022\"";

/// The furnace profile of the copper compacts: a constant 1293 K.
pub const AT_1293_K: &str = "{ constant = 1293.0 }";

/// The `[particles]` body of a packing file.
pub fn file_particles(packing: &Path) -> String {
    format!("source = \"file\"\nfile = \"{}\"", packing.display())
}

/// The `[particles]` body of an FCC lattice of `cells`³ cells of touching 25 µm spheres.
pub fn fcc(cells: u32) -> String {
    format!("source = \"lattice\"\nlattice = \"fcc\"\ncells = [{cells}, {cells}, {cells}]\nradius = 25e-6\noverlap = 0.0")
}

/// The `[time]` body of the compact tests: until `end` [s], steps from 1 µs up to 10 s.
pub fn time_to(end: f64) -> String {
    format!("end = {end:?}\ndt = 1.0e-6\ndt_max = 10.0")
}

/// The text of an isothermal compact case (`kind = "compact"`): `[time]` body `time` (e.g.
/// [`time_to`]), no snapshots, VTU or HDF5, one `[[materials]]` entry per body of `materials`,
/// `[particles]` body `particles`, the furnace following `profile` (an inline TOML table, e.g.
/// [`AT_1293_K`]). Tables of further sections may be appended.
pub fn compact_text(time: &str, materials: &[&str], particles: &str, profile: &str) -> String {
    let mut t = format!("kind = \"compact\"\n[time]\n{time}\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n");
    for m in materials {
        t.push_str(&format!("[[materials]]\n{m}\n"));
    }
    t.push_str(&format!("[particles]\n{particles}\n[thermal]\nmode = \"isothermal\"\nfurnace = {{ profile = {profile} }}\n"));
    t
}

/// The text of the copper compact of the tests: the copper preset on the packing file `packing`
/// in a furnace at 1293 K until `end` [s] (steps from 1 µs up to 10 s).
pub fn copper_compact_text(packing: &Path, end: f64) -> String {
    compact_text(&time_to(end), &[COPPER], &file_particles(packing), AT_1293_K)
}

/// A case `text` parsed, with the overrides `sets` (`key.path=value`) applied.
pub fn case_value(text: &str, sets: &[&str]) -> toml::Value {
    let mut v = toml::Value::Table(text.parse::<toml::Table>().unwrap_or_else(|e| panic!("{e}\n{text}")));
    for s in sets {
        sinterdem::config::apply_override(&mut v, s).unwrap();
    }
    v
}

/// The copper compact of the tests ([`copper_compact_text`]) with the overrides `sets` applied.
pub fn copper_compact(packing: &Path, end: f64, sets: &[&str]) -> toml::Value {
    case_value(&copper_compact_text(packing, end), sets)
}

/// The edge of the random periodic copper packing `cases/data/periodic-copper-500.csv` (500
/// spheres, 50 µm ± 10 %) [m].
pub const PERIODIC_COPPER_BOX: f64 = 3.690793753101957e-4;

/// The `[particles]` body of the random periodic copper packing, with its periodic box.
pub fn periodic_copper_particles() -> String {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/data/periodic-copper-500.csv");
    let b = PERIODIC_COPPER_BOX;
    format!(
        "{}
periodic_box = [{b:e}, {b:e}, {b:e}]",
        file_particles(&file)
    )
}

/// An isothermal copper compact at 1293 K until `end` [s] on `particles`, periodic, with the
/// `[mechanics.cell]` body `cell` and the overrides `sets`.
pub fn periodic_copper_case(end: f64, particles: &str, cell: &str, sets: &[&str]) -> toml::Value {
    let text = compact_text(&time_to(end), &[COPPER], particles, AT_1293_K) + &format!("[mechanics]\nboundary = \"periodic\"\n[mechanics.cell]\n{cell}\n");
    case_value(&text, sets)
}

/// Prepares and runs the compact case `v` into `out`; its summary.
pub fn run_compact(v: toml::Value, out: &Path) -> serde_json::Value {
    let sim = sinterdem::coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    sinterdem::kinds::compact::run(sim, out, false, &mut |_| {}).unwrap()
}

/// Steps `sim` to its end time.
pub fn advance_to_end(sim: &mut sinterdem::coupled::Simulation) {
    while sim.t < sim.settings.end {
        sim.advance_step(&mut |_| {}).unwrap();
    }
}

/// xorshift64: a seeded generator without an extra crate.
pub fn uniform(s: &mut u64) -> f64 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    (*s >> 11) as f64 / (1u64 << 53) as f64
}

/// A periodic random packing: `n` spheres of diameters `d (1 ± spread)` (uniform) placed at random
/// in a cubic box at nominal solid fraction `phi`, overlaps removed by Jacobi relaxation sweeps
/// under the minimum image (soft spheres pushed apart along their branch), then the box and the
/// centres shrunk by λ = 1 − h/2 so that pairs left in contact overlap by about `h` radii (the
/// "sintered" necks); at most `sweeps` relaxation sweeps (it stops once no overlap exceeds
/// 1e-5 d). Returns centres, radii and the box edge [m].
pub fn random_periodic(n: usize, d: f64, spread: f64, phi: f64, h: f64, seed: u64, sweeps: usize) -> (Vec<Vector3<f64>>, Vec<f64>, f64) {
    let mut s = seed.max(1);
    let rad: Vec<f64> = (0..n).map(|_| 0.5 * d * (1.0 + spread * (2.0 * uniform(&mut s) - 1.0))).collect();
    let vol: f64 = rad.iter().map(|r| 4.0 / 3.0 * std::f64::consts::PI * r * r * r).sum();
    let l = (vol / phi).cbrt();
    let bbox = Vector3::repeat(l);
    let mut pos: Vec<Vector3<f64>> = (0..n).map(|_| Vector3::new(uniform(&mut s), uniform(&mut s), uniform(&mut s)) * l).collect();
    for _sweep in 0..sweeps {
        let pairs = touching_pairs_periodic(&pos, &rad, bbox, 0.0);
        let mut shift = vec![Vector3::zeros(); n];
        let mut worst: f64 = 0.0;
        for p in &pairs {
            let (i, j) = (p.i as usize, p.j as usize);
            let sh = Vector3::new(p.shift[0] as f64, p.shift[1] as f64, p.shift[2] as f64) * l;
            let wrap = |x: Vector3<f64>| x.map(|c| c.rem_euclid(l));
            let b = wrap(pos[j]) + sh - wrap(pos[i]);
            let dist = b.norm();
            let overlap = rad[i] + rad[j] - dist;
            worst = worst.max(overlap / d);
            let u = b / dist.max(1e-30);
            // each moves 0.3 of the overlap apart (under-relaxed: several neighbours push at once)
            shift[i] -= 0.3 * overlap * u;
            shift[j] += 0.3 * overlap * u;
        }
        for (x, dx) in pos.iter_mut().zip(&shift) {
            *x = (*x + dx).map(|c| c.rem_euclid(l));
        }
        if worst < 1e-5 {
            break;
        }
    }
    let lambda = 1.0 - 0.5 * h;
    (pos.iter().map(|x| x * lambda).collect(), rad, l * lambda)
}
