//! Configuration errors a user can act on (issue 14 item 7): `sinterdem check` on broken copies of
//! the bundled cases names the file, line and column of the key at fault (or the `--set` that set
//! it), the full key, the nearest valid key for a typo, the expected type in plain words, and for a
//! key given twice the key, its table and the line of its first definition. `time.end` is the end
//! time of pair cases too.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

/// A copy of the bundled case `name` with `from` replaced by `to` (which must occur once).
fn edited(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(Path::new("cases").join(name)).unwrap();
    assert_eq!(text.matches(from).count(), 1, "{from:?} in {name}");
    let p = dir.join(name);
    std::fs::write(&p, text.replace(from, to)).unwrap();
    p
}

/// The 1-based line of the first line of `path` that starts with `start`.
fn line_of(path: &Path, start: &str) -> usize {
    std::fs::read_to_string(path).unwrap().lines().position(|l| l.starts_with(start)).unwrap() + 1
}

/// `sinterdem check PATH --set …`: the error line on stderr (the check must fail).
fn check_err(path: &Path, sets: &[&str]) -> String {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sinterdem"));
    c.arg("check").arg(path);
    for s in sets {
        c.arg("--set").arg(s);
    }
    let out = c.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "{} {sets:?} was accepted: {}", path.display(), String::from_utf8_lossy(&out.stdout));
    assert!(!err.contains("panicked"), "{err}");
    err.trim().to_string()
}

fn has(e: &str, want: &[&str]) {
    for w in want {
        assert!(e.contains(w), "expected {w:?} in:\n{e}");
    }
}

#[test]
fn unknown_keys_name_file_line_and_the_nearest_valid_key() {
    let d = common::tmp_dir("unknown");
    // a typo inside a section
    let p = edited(&d, "hot-plate.toml", "dt = 1.0 ", "dtt = 1.0 ");
    let e = check_err(&p, &[]);
    has(&e, &[&format!("{}:{}:1: time.dtt: unknown key; did you mean `time.dt`?", p.display(), line_of(&p, "dtt")), "keys allowed in [time]: end, dt, scheme"]);
    // a typo in a section name
    let p = edited(&d, "hot-plate.toml", "[output]", "[outptu]");
    has(&check_err(&p, &[]), &[&format!(":{}:2: outptu: unknown key; did you mean `output`?", line_of(&p, "[outptu]")), "keys allowed at the top level"]);
    // explicit_sinter and generate cases too
    let p = edited(&d, "luding-sintering-time.toml", "radius_spread = 0.2", "radius_sprad = 0.2");
    has(&check_err(&p, &[]), &[&format!(":{}:1: sample.radius_sprad: unknown key; did you mean `sample.radius_spread`?", line_of(&p, "radius_sprad"))]);
    let p = edited(&d, "green-copper.toml", "[packing.size]", "[packing.sise]");
    has(&check_err(&p, &[]), &["packing.sise: unknown key; did you mean `packing.size`?"]);
    // a key nothing resembles: no guess, the list
    let p = edited(&d, "hot-plate.toml", "dt = 1.0 ", "zzzz = 1.0 ");
    let e = check_err(&p, &[]);
    has(&e, &["time.zzzz: unknown key (keys allowed in [time]: end, dt"]);
    assert!(!e.contains("did you mean"), "{e}");
    // from --set: the override is named, not a line of the file
    let p = Path::new("cases/pair-copper.toml");
    has(&check_err(p, &["pair.radus=1e-5"]), &["pair.radus: unknown key; did you mean `pair.radius`?", "(set by --set pair.radus=1e-5)"]);
    // a misspelt value of a closed list
    let p = edited(&d, "hot-plate.toml", "scheme = \"bdf2\"", "scheme = \"bdf3\"");
    has(
        &check_err(&p, &[]),
        &[&format!(":{}:1: time.scheme: \"bdf3\" is not a known value; did you mean \"bdf2\"?", line_of(&p, "scheme")), "\"crank_nicolson\""],
    );
    // a missing key points at its table
    // (time.end is not: it defaults to the end of the heating profile, issue 25)
    let p = edited(&d, "hot-plate.toml", "dt = 1.0 ", "# dt = 1.0 ");
    has(&check_err(&p, &[]), &[&format!(":{}:2: time.dt: missing: this key is required in [time]", line_of(&p, "[time]"))]);
}

#[test]
fn type_errors_are_said_in_plain_words_with_the_line() {
    let d = common::tmp_dir("types");
    let cases: [(&str, &str, &str, &str, &str); 5] = [
        ("hot-plate.toml", "snapshots = 10", "snapshots = \"ten\"", "snapshots", "output.snapshots: expected a number, got the text \"ten\""),
        ("hot-plate.toml", "cells = [8, 8, 12]", "cells = [8, 8.5, 12]", "cells", "particles.cells: expected a whole number >= 0, got the number 8.5"),
        ("hot-plate.toml", "mode = \"network\"", "mode = 3", "mode", "thermal.mode: expected text (in quotes), got the whole number 3"),
        ("luding-sintering-time.toml", "pressures = [5e4]", "pressures = 5e4", "pressures", "walls.pressures: expected a list [..], got the number 50000"),
        ("pair-copper.toml", "plot = true", "plot = 1", "plot", "output.plot: expected true or false, got the whole number 1"),
    ];
    for (case, from, to, key, want) in cases {
        let p = edited(&d, case, from, to);
        let e = check_err(&p, &[]);
        has(&e, &[&format!("{}:{}:1: {want}", p.display(), line_of(&p, key))]);
        for rust in ["f64", "u32", "usize", "a sequence", "a boolean", "a string"] {
            assert!(!e.contains(rust), "Rust type name {rust:?} in: {e}");
        }
    }
    // from --set
    has(
        &check_err(Path::new("cases/luding-sintering-time.toml"), &["sample.particles=true"]),
        &["sample.particles: expected a number, got true (set by --set sample.particles=true)"],
    );
    // a range error gets its line too
    let p = edited(&d, "hot-plate.toml", "dt = 1.0 ", "dt = -1.0 ");
    has(&check_err(&p, &[]), &[&format!(":{}:1: time.dt = -1 is out of range: allowed [1e-15, 1e7] (s)", line_of(&p, "dt ="))]);
}

#[test]
fn duplicate_keys_name_the_key_its_table_and_both_lines() {
    let d = common::tmp_dir("dup");
    let p = edited(&d, "hot-plate.toml", "dt = 1.0 ", "dt = 1.0\ndt = 2.0 ");
    let first = line_of(&p, "dt = 1.0");
    has(
        &check_err(&p, &[]),
        &[&format!("{}:{}:1: duplicate key `dt` in [time] (first defined at line {first}): `time.dt` may be given once", p.display(), first + 1)],
    );
    let p = edited(&d, "pair-copper.toml", "[solver]", "[model]\nx = 1\n[solver]");
    let first = line_of(&p, "[model]");
    has(&check_err(&p, &[]), &[&format!("duplicate table [model] (first defined at line {first}); merge the two into one")]);
    let p = edited(&d, "pair-copper.toml", "kind = \"pair\"", "kind = \"pair\"\nkind = \"heat\"");
    has(&check_err(&p, &[]), &["duplicate key `kind` at the top level (first defined at line"]);
}

#[test]
fn time_end_is_the_end_time_of_pair_cases_too() {
    let d = common::tmp_dir("alias");
    // --set time.end on a pair case sets pair.end_time
    let case = sinterdem::config::load_case(Path::new("cases/pair-copper.toml"), &[]).unwrap();
    let params = sinterdem::kinds::RunParams { base_dir: PathBuf::from("cases"), plots: false, ..Default::default() };
    let s = sinterdem::kinds::run(&case, &["time.end=2".into()], &d.join("set"), &params).unwrap();
    assert_eq!(s.f64("final_time_s"), Some(2.0));
    // a pair case file may write [time] end = …
    let p = edited(&d, "pair-copper.toml", "end_time = 5000.0", "");
    let text = std::fs::read_to_string(&p).unwrap() + "\n[time]\nend = 3.0\n";
    std::fs::write(&p, text).unwrap();
    let v = sinterdem::config::load_case(&p, &[]).unwrap();
    let s = sinterdem::kinds::run(&v, &[], &d.join("file"), &params).unwrap();
    assert_eq!(s.f64("final_time_s"), Some(3.0));
    // … but not both, nor other [time] keys
    let p = edited(&d, "pair-copper.toml", "end_time = 5000.0", "end_time = 5000.0\n[time]\nend = 3.0\n[more]");
    let text = std::fs::read_to_string(&p).unwrap().replace("[more]", "");
    std::fs::write(&p, text).unwrap();
    has(&check_err(&p, &[]), &["time.end: and `pair.end_time` name the same end time of a pair case; give one of them"]);
    let p2 = d.join("p2.toml");
    std::fs::write(&p2, std::fs::read_to_string(&p).unwrap().replace("end_time = 5000.0\n", "").replace("end = 3.0", "end = 3.0\ndt = 1.0")).unwrap();
    has(&check_err(&p2, &[]), &["time.dt: unknown key: a pair case takes only `time.end` in [time] (the same as `pair.end_time`)"]);
}
