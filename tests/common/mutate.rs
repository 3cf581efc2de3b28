//! The case mutator shared by the fuzz targets (`tests/fuzz_check.rs`, `tests/fuzz_run.rs`;
//! each includes it with `#[path = "common/mutate.rs"] mod mutate;`): a seed corpus of case files,
//! proptest strategies of mutations and [`mutate`], which applies them to a seed.
//!
//! Mutations (1–4 per input): a leaf replaced by an extreme number (0, ±5e-324, ±1e300, NaN,
//! ±inf, 2^63, …), an integer, a string from the corpus's own strings (file names, kinds, laws,
//! schedules) or a hostile one, a bool, an array or a table; a leaf deleted; an unknown key
//! added; any range-table key set through the `--set` mechanism (`config::apply_override`); the
//! kind swapped; and, for one input in eight, byte-level edits of the TOML text ([`apply_raw`]).
#![allow(dead_code)]

use proptest::prelude::*;
use sinterdem::config::{apply_override, parse_case_str};
use std::path::{Path, PathBuf};

pub struct Seed {
    pub name: String,
    pub dir: PathBuf,
    pub value: toml::Value,
    /// Paths of every node (tables, arrays and leaves), root excluded.
    pub paths: Vec<Vec<Seg>>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    Key(String),
    Index(usize),
}

pub fn collect_paths(v: &toml::Value, prefix: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    match v {
        toml::Value::Table(t) => {
            for (k, x) in t {
                prefix.push(Seg::Key(k.clone()));
                out.push(prefix.clone());
                collect_paths(x, prefix, out);
                prefix.pop();
            }
        }
        toml::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                prefix.push(Seg::Index(i));
                out.push(prefix.clone());
                collect_paths(x, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

pub fn collect_strings(v: &toml::Value, out: &mut Vec<String>) {
    match v {
        toml::Value::String(s) => out.push(s.clone()),
        toml::Value::Table(t) => t.values().for_each(|x| collect_strings(x, out)),
        toml::Value::Array(a) => a.iter().for_each(|x| collect_strings(x, out)),
        _ => {}
    }
}

pub fn corpus(dirs: &[&str]) -> (Vec<Seed>, Vec<String>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for d in dirs {
        let mut f: Vec<PathBuf> =
            std::fs::read_dir(root.join(d)).unwrap().filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|x| x == "toml")).collect();
        f.sort();
        files.extend(f);
    }
    let mut strings: Vec<String> = [
        "",
        "x",
        "heat",
        "compact",
        "generate",
        "pair",
        "explicit_sinter",
        "/dev/zero",
        "/",
        "nonexistent.csv",
        "data/green-copper.csv",
        "../cases/data/green-titanium.csv",
        "far.csv",
        "tiny.csv",
        "good.csv",
        "fcc",
        "sc",
        "bcc",
        "file",
        "lattice",
        "isothermal",
        "network",
        "harmonic",
        "arithmetic",
        "cholesky",
        "cg",
        "amg",
        "auto",
        "rosenbrock4",
        "dopri5",
        "rk4_doubling",
        "linear",
        "fe_fit",
        "faces",
        "periodic",
        "seven_dof",
        "volume_conserving",
        "yade",
        "liggghts",
        "csv",
        "bdf2",
        "start 293 K, heat 1e300 K/min to 1273 K",
        "start 293 K, hold 1e-300 s",
        "start nan K",
        "start 293 K, heat 10 K/min to 5e-324 K",
        "z-",
        "x+",
        "q",
        "\u{feff}",
        "é\u{0}",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let mut seeds = Vec::new();
    for p in files {
        let text = std::fs::read_to_string(&p).unwrap();
        let value = parse_case_str(&text, "seed").unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        collect_strings(&value, &mut strings);
        let mut paths = Vec::new();
        collect_paths(&value, &mut Vec::new(), &mut paths);
        seeds.push(Seed { name: p.strip_prefix(root).unwrap().display().to_string(), dir: p.parent().unwrap().to_path_buf(), value, paths });
    }
    strings.sort();
    strings.dedup();
    (seeds, strings)
}

pub const NUMBERS: &[f64] = &[
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    2.0,
    3.0,
    5e-324,
    -5e-324,
    1e-300,
    1e300,
    -1e300,
    f64::MAX,
    f64::MIN,
    f64::MIN_POSITIVE,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e-15,
    1e-12,
    1e-9,
    1e-6,
    1e-3,
    1e3,
    1e6,
    1e9,
    1e12,
    9.3e18,
    1.9e19,
    200.0,
    201.0,
    1.0000000000000002,
    0.9999999999999999,
    293.15,
    1e4,
    25e-6,
    0.64,
    0.72,
];
pub const INTS: &[i64] = &[0, -1, 1, 2, 3, 7, 200, 201, 65535, 65536, 1 << 32, 1 << 53, i64::MAX, i64::MIN];

#[derive(Debug, Clone)]
pub enum Mutation {
    Number {
        node: usize,
        value: f64,
    },
    Scale {
        node: usize,
        exp: i32,
    },
    Int {
        node: usize,
        value: i64,
    },
    Text {
        node: usize,
        pick: usize,
    },
    Bool {
        node: usize,
        value: bool,
    },
    Array {
        node: usize,
        len: usize,
        value: f64,
    },
    Table {
        node: usize,
    },
    Delete {
        node: usize,
    },
    Unknown {
        node: usize,
    },
    SetKey {
        key: usize,
        value: f64,
    },
    Kind {
        pick: usize,
    },
    /// A range-table key that the case has set to a value inside its documented range: an edge
    /// (`edge` 0: the lower, 1: the upper, the next representable value for an open one) or a
    /// point `at` ∈ [0, 1) between them (log-uniform for a positive range).
    InRange {
        key: usize,
        edge: u8,
        at: f64,
    },
}

pub fn number() -> impl Strategy<Value = f64> {
    prop_oneof![4 => proptest::sample::select(NUMBERS), 1 => any::<f64>()]
}

pub fn mutation() -> impl Strategy<Value = Mutation> {
    let n = any::<usize>();
    prop_oneof![
        6 => (n, number()).prop_map(|(node, value)| Mutation::Number { node, value }),
        2 => (n, -320i32..320).prop_map(|(node, exp)| Mutation::Scale { node, exp }),
        2 => (n, proptest::sample::select(INTS)).prop_map(|(node, value)| Mutation::Int { node, value }),
        3 => (n, any::<usize>()).prop_map(|(node, pick)| Mutation::Text { node, pick }),
        1 => (n, any::<bool>()).prop_map(|(node, value)| Mutation::Bool { node, value }),
        1 => (n, 0usize..5, number()).prop_map(|(node, len, value)| Mutation::Array { node, len, value }),
        1 => n.prop_map(|node| Mutation::Table { node }),
        2 => n.prop_map(|node| Mutation::Delete { node }),
        1 => n.prop_map(|node| Mutation::Unknown { node }),
        5 => (any::<usize>(), number()).prop_map(|(key, value)| Mutation::SetKey { key, value }),
        1 => any::<usize>().prop_map(|pick| Mutation::Kind { pick }),
    ]
}

#[derive(Debug, Clone)]
pub struct Input {
    pub seed: usize,
    pub mutations: Vec<Mutation>,
    /// Byte edits of the serialised text: (position, byte); empty for most inputs.
    pub raw: Vec<(usize, u8)>,
}

pub fn input() -> impl Strategy<Value = Input> {
    (
        any::<usize>(),
        proptest::collection::vec(mutation(), 1..5),
        prop_oneof![7 => Just(Vec::new()), 1 => proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4)],
    )
        .prop_map(|(seed, mutations, raw)| Input { seed, mutations, raw })
}

pub fn node_mut<'a>(root: &'a mut toml::Value, path: &[Seg]) -> Option<&'a mut toml::Value> {
    let mut cur = root;
    for s in path {
        cur = match (cur, s) {
            (toml::Value::Table(t), Seg::Key(k)) => t.get_mut(k)?,
            (toml::Value::Array(a), Seg::Index(i)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

pub fn toml_number(v: f64) -> toml::Value {
    toml::Value::Float(v)
}

pub fn override_text(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{v:e}")
    }
}

/// The run-path mutations: mostly in-range values of keys the case sets ([`Mutation::InRange`])
/// and scalings of its leaves, else any [`mutation`] (most of which `check` refuses).
pub fn run_mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        5 => (any::<usize>(), 0u8..6, 0.0..1.0f64).prop_map(|(key, edge, at)| Mutation::InRange { key, edge, at }),
        2 => (any::<usize>(), -3i32..4).prop_map(|(node, exp)| Mutation::Scale { node, exp }),
        2 => mutation(),
    ]
}

/// An input of the run-path fuzzer: one or two [`run_mutation`]s, rarely byte edits.
pub fn run_input() -> impl Strategy<Value = Input> {
    (
        any::<usize>(),
        proptest::collection::vec(run_mutation(), 1..3),
        prop_oneof![15 => Just(Vec::new()), 1 => proptest::collection::vec((any::<usize>(), any::<u8>()), 1..3)],
    )
        .prop_map(|(seed, mutations, raw)| Input { seed, mutations, raw })
}

/// The leaf at the dotted `key` (array indices as numbers), if the case has it.
fn leaf<'a>(v: &'a toml::Value, key: &str) -> Option<&'a toml::Value> {
    let mut cur = v;
    for part in key.split('.') {
        cur = match cur {
            toml::Value::Table(t) => t.get(part)?,
            toml::Value::Array(a) => a.get(part.parse::<usize>().ok()?)?,
            _ => return None,
        };
    }
    Some(cur)
}

/// The value of an [`Mutation::InRange`] in the range `r`.
fn in_range(r: &sinterdem::config::ranges::Range, edge: u8, at: f64) -> f64 {
    let lo = if r.lo_open { r.lo.next_up() } else { r.lo };
    let hi = if r.hi_open { r.hi.next_down() } else { r.hi };
    match edge {
        0 => lo,
        1 if hi.is_finite() => hi,
        _ => {
            let hi = if hi.is_finite() { hi } else { lo.abs().max(1.0) * 1e12 };
            if lo > 0.0 { (lo.ln() + at * (hi.ln() - lo.ln())).exp().clamp(lo, hi) } else { (lo + at * (hi - lo)).clamp(lo, hi) }
        }
    }
}

/// Range-table keys with every `*` as index 0 (arrays) — also the names a table key may take.
pub fn set_keys() -> Vec<String> {
    sinterdem::calibrate::every_table().iter().flat_map(|t| t.iter()).map(|r| r.key.replace('*', "0")).collect()
}

pub fn mutate(seed: &Seed, input: &Input, strings: &[String], keys: &[String]) -> toml::Value {
    let mut v = seed.value.clone();
    let kinds = ["heat", "compact", "generate", "pair", "explicit_sinter", "bogus"];
    for m in &input.mutations {
        let pick_path = |node: usize| -> Option<&Vec<Seg>> { if seed.paths.is_empty() { None } else { Some(&seed.paths[node % seed.paths.len()]) } };
        match m {
            Mutation::SetKey { key, value } => {
                let _ = apply_override(&mut v, &format!("{}={}", keys[key % keys.len()], override_text(*value)));
            }
            Mutation::InRange { key, edge, at } => {
                let rows: Vec<_> =
                    sinterdem::calibrate::every_table().iter().flat_map(|t| t.iter()).filter(|r| leaf(&v, &r.key.replace('*', "0")).is_some()).collect();
                if rows.is_empty() {
                    continue;
                }
                let r = rows[key % rows.len()];
                let k = r.key.replace('*', "0");
                let x = in_range(r, *edge, *at);
                let text = if matches!(leaf(&v, &k), Some(toml::Value::Integer(_))) { format!("{}", x.round() as i64) } else { override_text(x) };
                let _ = apply_override(&mut v, &format!("{k}={text}"));
            }
            Mutation::Kind { pick } => {
                let _ = apply_override(&mut v, &format!("kind=\"{}\"", kinds[pick % kinds.len()]));
            }
            Mutation::Delete { node } | Mutation::Unknown { node } => {
                let Some(path) = pick_path(*node) else { continue };
                let (last, parent) = path.split_last().unwrap();
                let Some(p) = node_mut(&mut v, parent) else { continue };
                match (p, last, m) {
                    (toml::Value::Table(t), Seg::Key(k), Mutation::Delete { .. }) => {
                        t.remove(k);
                    }
                    (toml::Value::Array(a), Seg::Index(i), Mutation::Delete { .. }) if *i < a.len() => {
                        a.remove(*i);
                    }
                    (toml::Value::Table(t), _, Mutation::Unknown { .. }) => {
                        t.insert("fuzz_unknown_key".into(), toml::Value::Integer(1));
                    }
                    _ => {}
                }
            }
            _ => {
                let node = match m {
                    Mutation::Number { node, .. }
                    | Mutation::Scale { node, .. }
                    | Mutation::Int { node, .. }
                    | Mutation::Text { node, .. }
                    | Mutation::Bool { node, .. }
                    | Mutation::Array { node, .. }
                    | Mutation::Table { node } => *node,
                    _ => unreachable!(),
                };
                let Some(path) = pick_path(node) else { continue };
                let path = path.clone();
                let Some(slot) = node_mut(&mut v, &path) else { continue };
                *slot = match m {
                    Mutation::Number { value, .. } => toml_number(*value),
                    Mutation::Scale { exp, .. } => match &*slot {
                        toml::Value::Float(x) => toml_number(*x * 10f64.powi(*exp)),
                        toml::Value::Integer(x) => toml_number(*x as f64 * 10f64.powi(*exp)),
                        other => other.clone(),
                    },
                    Mutation::Int { value, .. } => toml::Value::Integer(*value),
                    Mutation::Text { pick, .. } => toml::Value::String(strings[pick % strings.len()].clone()),
                    Mutation::Bool { value, .. } => toml::Value::Boolean(*value),
                    Mutation::Array { len, value, .. } => toml::Value::Array(vec![toml_number(*value); *len]),
                    Mutation::Table { .. } => toml::Value::Table(toml::Table::new()),
                    _ => unreachable!(),
                };
            }
        }
    }
    v
}

pub fn env_num(name: &str, default: f64) -> f64 {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

/// The input's byte edits applied to the serialised case `value`, parsed again (`None`: no
/// edits); an `Err` is a case that no longer parses.
pub fn apply_raw(value: &toml::Value, inp: &Input) -> Result<toml::Value, sinterdem::error::ConfigError> {
    let mut text = toml::to_string(value).unwrap_or_default().into_bytes();
    for &(pos, b) in &inp.raw {
        if !text.is_empty() {
            let p = pos % text.len();
            text[p] = b;
        }
    }
    parse_case_str(&String::from_utf8_lossy(&text), "fuzz")
}
