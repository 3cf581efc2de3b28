//! Every bundled case (`cases/*.toml`, `cases/titanium/*.toml`) runs briefly — shortened through
//! the `--set` override mechanism (`config::apply_override`) — and no output file of it holds NaN,
//! inf or null: not `summary.json`, not `series.csv`, not any history or other CSV (issue 16).

use std::path::{Path, PathBuf};
use std::process::Command;

/// The overrides that shorten a case of `kind` (same physics, less simulated time / fewer particles).
fn shorten(kind: &str, name: &str) -> Vec<&'static str> {
    let mut s = match kind {
        "heat" => vec!["time.end=5.0", "output.snapshots=2"],
        // a few dozen adaptive steps from dt0; the analyses at t = 0 still run
        "compact" => {
            vec!["time.end=2.0", "output.snapshots=2", "output.checkpoint_every=10", "output.conductivity_at=[0.0]", "output.correction_histogram_at=[]"]
        }
        "generate" => vec!["packing.particles=60"],
        "pair" => vec![],
        "explicit_sinter" => vec![
            "protocol.t_prepare=0.003",
            "protocol.t_heat=0.001",
            "protocol.t_sinter=[0.001]",
            "protocol.t_cool=0.001",
            "protocol.t_relax=0.001",
            "compression.max_strain=0.005",
            "walls.pressures=[5e3]",
            "sample.particles=40",
        ],
        _ => panic!("{name}: unknown kind {kind}"),
    };
    if name == "pair-copper.toml" {
        s.push("pair.end_time=500.0");
    }
    if name.starts_with("luding") {
        s.push("protocol.t0_sinter=0.001");
    }
    if name.starts_with("titanium-compact") {
        // 3619 particles: 14 steps are enough to pass every stage (about 25 s)
        s[0] = "time.end=0.2";
        s.retain(|x| !x.starts_with("output.conductivity_at"));
    }
    s
}

fn bad_token(t: &str) -> bool {
    let t = t.trim().trim_matches('"').to_ascii_lowercase();
    matches!(t.as_str(), "nan" | "-nan" | "+nan" | "inf" | "-inf" | "+inf" | "infinity" | "-infinity" | "+infinity" | "null")
}

fn json_nulls(v: &serde_json::Value, path: &str, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Null => out.push(path.to_string()),
        serde_json::Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| json_nulls(x, &format!("{path}[{i}]"), out)),
        serde_json::Value::Object(o) => o.iter().for_each(|(k, x)| json_nulls(x, &format!("{path}.{k}"), out)),
        _ => {}
    }
}

/// Nulls allowed anywhere: none (optional fields are left out, `stop_reason` says "end time reached").
const OPTIONAL_NULLS: &[(&str, &str)] = &[];

/// Every NaN/inf/null in the CSV and JSON files under `dir`: "file: where".
fn scan(dir: &Path) -> (usize, Vec<String>) {
    let mut bad = Vec::new();
    let mut files = 0;
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            let ext = p.extension().and_then(|x| x.to_str()).unwrap_or("");
            if ext == "csv" {
                files += 1;
                let text = std::fs::read_to_string(&p).unwrap();
                for (k, line) in text.lines().enumerate() {
                    if line.starts_with('#') {
                        continue;
                    }
                    if let Some(t) = line.split([',', ' ', '\t']).find(|t| bad_token(t)) {
                        bad.push(format!("{}: line {}: {t}", p.display(), k + 1));
                        break;
                    }
                }
            } else if ext == "json" {
                files += 1;
                let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
                let mut nulls = Vec::new();
                json_nulls(&v, "", &mut nulls);
                let fname = p.file_name().unwrap().to_string_lossy().to_string();
                nulls.retain(|n| !OPTIONAL_NULLS.contains(&(fname.as_str(), n.as_str())));
                bad.extend(nulls.into_iter().map(|n| format!("{}: {n} is null", p.display())));
            }
        }
    }
    (files, bad)
}

/// Fields of `summary.json` that measure the machine, not the physics: wall times (`wall_*`,
/// `seconds_*`), thread count, and every `*_s` timing inside a `*profile*` or `timing*` object.
fn normalise(v: &mut serde_json::Value, parent: &str) {
    if let serde_json::Value::Object(o) = v {
        o.retain(|k, _| {
            let timing_parent = parent.contains("profile") || parent.starts_with("timing");
            !(k.starts_with("wall_") || k == "threads" || k.starts_with("timing") || k.starts_with("seconds_") || (timing_parent && k.ends_with("_s")))
        });
        for (k, x) in o.iter_mut() {
            normalise(x, k);
        }
    } else if let serde_json::Value::Array(a) = v {
        a.iter_mut().for_each(|x| normalise(x, parent));
    }
}

/// SHA-256 of `series.csv` and of `summary.json` without the machine-dependent fields (issue 22:
/// behaviour unchanged by the move to the `kinds/` floor), as `name\tfile\thex` lines.
fn checksums(name: &str, out: &Path) -> Vec<String> {
    use sha2::{Digest, Sha256};
    let mut lines = Vec::new();
    for file in ["series.csv", "summary.json"] {
        let p = out.join(file);
        let Ok(text) = std::fs::read_to_string(&p) else { continue };
        let bytes = if file == "summary.json" {
            let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
            normalise(&mut v, "");
            serde_json::to_string(&v).unwrap()
        } else {
            text
        };
        let h = Sha256::digest(bytes.as_bytes());
        lines.push(format!("{name}\t{file}\t{}", h.iter().map(|b| format!("{b:02x}")).collect::<String>()));
    }
    lines
}

/// Checksums recorded with the code before the move (`SINTERDEM_RECORD_CHECKSUMS=1` rewrites them).
const CHECKSUMS: &str = "tests/data/bundled-checksums.tsv";

fn cases() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v = Vec::new();
    for d in ["cases", "cases/titanium"] {
        let mut f: Vec<PathBuf> =
            std::fs::read_dir(root.join(d)).unwrap().flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|x| x == "toml")).collect();
        f.sort();
        v.extend(f);
    }
    v
}

#[test]
fn every_bundled_case_runs_briefly_without_nan_inf_or_null() {
    let out_root = std::env::temp_dir().join(format!("sinterdem-bundled-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out_root);
    let mut failures = Vec::new();
    let mut report = Vec::new();
    let mut sums = Vec::new();
    for case in cases() {
        let name = case.file_name().unwrap().to_string_lossy().to_string();
        let v = sinterdem::config::load_case(&case, &[]).unwrap();
        let kind = v.get("kind").and_then(|k| k.as_str()).unwrap_or("heat").to_string();
        let sets = shorten(&kind, &name);
        let out = out_root.join(name.trim_end_matches(".toml"));
        let t0 = std::time::Instant::now();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_sinterdem"));
        // a case with [rve] runs as `sinterdem rve` (docs/rve.md): one short branch point
        let rve = v.get("rve").is_some();
        cmd.arg(if rve { "rve" } else { "run" }).arg(&case).arg("--out").arg(&out).arg("--quiet");
        if rve {
            cmd.args(["--set", "rve.at=[2.0]", "--set", "rve.interval=0.2"]);
        }
        for s in &sets {
            cmd.arg("--set").arg(s);
        }
        let o = cmd.output().unwrap();
        let secs = t0.elapsed().as_secs_f64();
        if !o.status.success() {
            failures.push(format!("{name}: exit {:?}: {}", o.status.code(), String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")));
            continue;
        }
        let (files, bad) = scan(&out);
        if files == 0 || !out.join("summary.json").exists() {
            failures.push(format!("{name}: no summary.json / no CSV written"));
        }
        failures.extend(bad.into_iter().take(5).map(|b| format!("{name}: {b}")));
        sums.extend(checksums(&name, &out));
        report.push(format!("{name} ({kind}): {secs:.1} s, {files} files"));
    }
    eprintln!("{}", report.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(CHECKSUMS);
    if std::env::var("SINTERDEM_RECORD_CHECKSUMS").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, sums.join("\n") + "\n").unwrap();
    }
    let recorded = std::fs::read_to_string(&path).unwrap();
    let recorded: Vec<&str> = recorded.lines().collect();
    let changed: Vec<String> =
        sums.iter().filter(|s| !recorded.contains(&s.as_str())).map(|s| s.rsplit_once('\t').map_or(s.clone(), |(k, _)| k.to_string())).collect();
    assert!(
        recorded.len() == sums.len() && changed.is_empty(),
        "outputs differ from {CHECKSUMS} ({} recorded, {} now): {changed:?}",
        recorded.len(),
        sums.len()
    );
    let _ = std::fs::remove_dir_all(&out_root);
}
