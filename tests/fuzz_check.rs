//! Fuzz target of the case parser and `sinterdem check` (issue 16): a proptest property over case
//! files mutated from a seed corpus — the bundled `cases/*.toml`, `cases/titanium/*.toml` and the
//! issue's reproducers in `tests/fuzz-corpus/` — asserting that parse + check never panics
//! (each execution runs under `catch_unwind`; a panic fails the property with the mutated case).
//!
//! Bounded for CI: `SINTERDEM_FUZZ_CASES` executions (default 150000, about 60 s in release on 2 cores) and at most
//! `SINTERDEM_FUZZ_SECONDS` seconds (default 60); the executions done, the corpus size and the
//! rate are printed (`--nocapture`) and written to `target/fuzz-check-stats.json`.
//! `SINTERDEM_FUZZ_SEED` picks the random stream (default fixed, so CI is reproducible).
//!
//! Mutations (1–4 per execution): a leaf replaced by an extreme number (0, ±5e-324, ±1e300, NaN,
//! ±inf, 2^63, …), an integer, a string from the corpus's own strings (file names, kinds, laws,
//! schedules) or a hostile one, a bool, an array or a table; a leaf deleted; an unknown key
//! added; any range-table key set through the `--set` mechanism (`config::apply_override`); the
//! kind swapped; and, for one execution in eight, byte-level edits of the TOML text.

use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use sinterdem::config::{apply_override, parse_case_str};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

struct Seed {
    name: String,
    dir: PathBuf,
    value: toml::Value,
    /// Paths of every node (tables, arrays and leaves), root excluded.
    paths: Vec<Vec<Seg>>,
}

#[derive(Debug, Clone, PartialEq)]
enum Seg {
    Key(String),
    Index(usize),
}

fn collect_paths(v: &toml::Value, prefix: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
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

fn collect_strings(v: &toml::Value, out: &mut Vec<String>) {
    match v {
        toml::Value::String(s) => out.push(s.clone()),
        toml::Value::Table(t) => t.values().for_each(|x| collect_strings(x, out)),
        toml::Value::Array(a) => a.iter().for_each(|x| collect_strings(x, out)),
        _ => {}
    }
}

fn corpus() -> (Vec<Seed>, Vec<String>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for d in ["cases", "cases/titanium", "tests/fuzz-corpus"] {
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

const NUMBERS: &[f64] = &[
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
const INTS: &[i64] = &[0, -1, 1, 2, 3, 7, 200, 201, 65535, 65536, 1 << 32, 1 << 53, i64::MAX, i64::MIN];

#[derive(Debug, Clone)]
enum Mutation {
    Number { node: usize, value: f64 },
    Scale { node: usize, exp: i32 },
    Int { node: usize, value: i64 },
    Text { node: usize, pick: usize },
    Bool { node: usize, value: bool },
    Array { node: usize, len: usize, value: f64 },
    Table { node: usize },
    Delete { node: usize },
    Unknown { node: usize },
    SetKey { key: usize, value: f64 },
    Kind { pick: usize },
}

fn number() -> impl Strategy<Value = f64> {
    prop_oneof![4 => proptest::sample::select(NUMBERS), 1 => any::<f64>()]
}

fn mutation() -> impl Strategy<Value = Mutation> {
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
struct Input {
    seed: usize,
    mutations: Vec<Mutation>,
    /// Byte edits of the serialised text: (position, byte); empty for most inputs.
    raw: Vec<(usize, u8)>,
}

fn input() -> impl Strategy<Value = Input> {
    (
        any::<usize>(),
        proptest::collection::vec(mutation(), 1..5),
        prop_oneof![7 => Just(Vec::new()), 1 => proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4)],
    )
        .prop_map(|(seed, mutations, raw)| Input { seed, mutations, raw })
}

fn node_mut<'a>(root: &'a mut toml::Value, path: &[Seg]) -> Option<&'a mut toml::Value> {
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

fn toml_number(v: f64) -> toml::Value {
    toml::Value::Float(v)
}

fn override_text(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{v:e}")
    }
}

/// Range-table keys with every `*` as index 0 (arrays) — also the names a table key may take.
fn set_keys() -> Vec<String> {
    sinterdem::calibrate::every_table().iter().flat_map(|t| t.iter()).map(|r| r.key.replace('*', "0")).collect()
}

fn mutate(seed: &Seed, input: &Input, strings: &[String], keys: &[String]) -> toml::Value {
    let mut v = seed.value.clone();
    let kinds = ["heat", "compact", "generate", "pair", "explicit_sinter", "bogus"];
    for m in &input.mutations {
        let pick_path = |node: usize| -> Option<&Vec<Seg>> { if seed.paths.is_empty() { None } else { Some(&seed.paths[node % seed.paths.len()]) } };
        match m {
            Mutation::SetKey { key, value } => {
                let _ = apply_override(&mut v, &format!("{}={}", keys[key % keys.len()], override_text(*value)));
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

fn env_num(name: &str, default: f64) -> f64 {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

#[test]
fn check_never_panics_on_mutated_cases() {
    // the memory check refuses scenes above ~12 000 heat particles, so that an execution stays
    // fast (the check path is the same; only the threshold is lower than the machine's memory)
    // SAFETY: the only test of this binary, before any thread is started.
    unsafe { std::env::set_var("SINTERDEM_MEMORY_AVAILABLE", "5e7") };
    let cases = env_num("SINTERDEM_FUZZ_CASES", 150000.0) as u32;
    let budget = env_num("SINTERDEM_FUZZ_SECONDS", 60.0);
    let seed = env_num("SINTERDEM_FUZZ_SEED", 16.0) as u64;
    let (seeds, strings) = corpus();
    let keys = set_keys();
    let executed = AtomicU64::new(0);
    let accepted = AtomicU64::new(0);
    let start = Instant::now();
    let config = Config { cases, failure_persistence: None, max_shrink_iters: 200, ..Config::default() };
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    let mut runner = TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &bytes));
    let result = runner.run(&input(), |inp| {
        if start.elapsed().as_secs_f64() > budget {
            return Ok(());
        }
        let s = &seeds[inp.seed % seeds.len()];
        let value = mutate(s, &inp, &strings, &keys);
        let dir = s.dir.clone();
        let outcome = std::panic::catch_unwind(|| {
            let value = if inp.raw.is_empty() {
                Ok(value.clone())
            } else {
                let mut text = toml::to_string(&value).unwrap_or_default().into_bytes();
                for &(pos, b) in &inp.raw {
                    if !text.is_empty() {
                        let p = pos % text.len();
                        text[p] = b;
                    }
                }
                parse_case_str(&String::from_utf8_lossy(&text), "fuzz")
            };
            match value {
                Ok(v) => sinterdem::calibrate::check_file(&v, &[], &dir).is_ok(),
                Err(_) => false,
            }
        });
        executed.fetch_add(1, Ordering::Relaxed);
        match outcome {
            Ok(ok) => {
                accepted.fetch_add(ok as u64, Ordering::Relaxed);
                Ok(())
            }
            Err(p) => {
                let msg = p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default();
                Err(TestCaseError::fail(format!("check panicked ({msg}) on seed {} mutated to:\n{}", s.name, toml::to_string(&value).unwrap_or_default())))
            }
        }
    });
    let secs = start.elapsed().as_secs_f64();
    let n = executed.load(Ordering::Relaxed);
    let stats = serde_json::json!({
        "executions": n,
        "accepted": accepted.load(Ordering::Relaxed),
        "corpus_files": seeds.len(),
        "seconds": secs,
        "executions_per_second": n as f64 / secs,
        "seed": seed,
    });
    eprintln!("fuzz check: {stats}");
    let _ = std::fs::write(Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-check-stats.json"), stats.to_string());
    if let Err(e) = result {
        panic!("{e}");
    }
}
