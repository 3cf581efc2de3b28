//! The shape of the house (docs/architecture.md, issue 22), checked on the source text:
//! - no import circle between the top-level modules of `src/` (the module graph is built from
//!   `use crate::…` and `crate::…::` paths; a strongly connected component of more than one
//!   module fails);
//! - no source file over 900 lines, apart from the single-concern numerical kernels that
//!   docs/architecture.md names in its "Long kernels" list;
//! - no function over 150 lines.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_FILE_LINES: usize = 900;
const MAX_FN_LINES: usize = 150;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The source with comments, string and character literals blanked (newlines kept), so that
/// braces and paths are only those of the code.
fn code_only(text: &str) -> String {
    let b: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    let keep_nl = |c: char, out: &mut String| out.push(if c == '\n' { '\n' } else { ' ' });
    while i < b.len() {
        let c = b[i];
        if c == '/' && b.get(i + 1) == Some(&'/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && b.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    keep_nl(b[i], &mut out);
                    i += 1;
                }
            }
        } else if c == 'r' && (b.get(i + 1) == Some(&'"') || b.get(i + 1) == Some(&'#')) && (i == 0 || !(b[i - 1].is_alphanumeric() || b[i - 1] == '_')) {
            // raw string r#"…"#
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if b.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == '"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                keep_nl(b[j], &mut out);
                j += 1;
            }
            out.push_str("\"\"");
            i = j;
        } else if c == '"' {
            i += 1;
            while i < b.len() && b[i] != '"' {
                if b[i] == '\\' {
                    i += 1;
                }
                if i < b.len() {
                    keep_nl(b[i], &mut out);
                }
                i += 1;
            }
            out.push_str("\"\"");
            i += 1;
        } else if c == '\'' && b.get(i + 2) == Some(&'\'') {
            out.push_str("' '");
            i += 3;
        } else if c == '\'' && b.get(i + 1) == Some(&'\\') {
            let mut j = i + 2;
            while j < b.len() && b[j] != '\'' {
                j += 1;
            }
            out.push_str("' '");
            i = j + 1;
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// The top-level module a source file belongs to (`src/heat/run.rs` → `heat`, `src/neck.rs` →
/// `neck`); None for the crate roots.
fn module_of(path: &Path) -> Option<String> {
    let rel = path.strip_prefix(root().join("src")).unwrap();
    let first = rel.components().next()?.as_os_str().to_string_lossy().to_string();
    let name = first.trim_end_matches(".rs").to_string();
    (!matches!(name.as_str(), "lib" | "main" | "bin")).then_some(name)
}

/// The top-level modules that `code` names through `crate::X` paths, `use crate::{X, …}` groups
/// included.
fn imports(code: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        let before = rest[..i].chars().last();
        rest = &rest[i + 7..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
            continue;
        }
        let t = rest.trim_start();
        if let Some(group) = t.strip_prefix('{') {
            // use crate::{a::b, c, d::{e, f}}: the first segment of every top-level item
            let mut depth = 0;
            let mut item = String::new();
            let mut at_start = true;
            for ch in group.chars() {
                match ch {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        if at_start && !item.is_empty() {
                            out.insert(item.clone());
                        }
                        at_start = true;
                        item.clear();
                        continue;
                    }
                    _ => {}
                }
                if depth == 0 && at_start {
                    if ch.is_alphanumeric() || ch == '_' {
                        item.push(ch);
                    } else if !item.is_empty() {
                        out.insert(item.clone());
                        at_start = false;
                    }
                }
            }
            if at_start && !item.is_empty() {
                out.insert(item);
            }
        } else {
            let name: String = t.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            if !name.is_empty() {
                out.insert(name);
            }
        }
    }
    out
}

/// Strongly connected components of more than one node (Tarjan).
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct S<'a> {
        g: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<String, usize>,
        low: BTreeMap<String, usize>,
        stack: Vec<String>,
        on: BTreeSet<String>,
        next: usize,
        out: Vec<Vec<String>>,
    }
    fn visit(s: &mut S, v: &str) {
        s.index.insert(v.to_string(), s.next);
        s.low.insert(v.to_string(), s.next);
        s.next += 1;
        s.stack.push(v.to_string());
        s.on.insert(v.to_string());
        let succ: Vec<String> = s.g.get(v).map(|x| x.iter().cloned().collect()).unwrap_or_default();
        for w in succ {
            if !s.index.contains_key(&w) {
                visit(s, &w);
                let lw = s.low[&w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.on.contains(&w) {
                let iw = s.index[&w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(&w);
                let done = w == v;
                comp.push(w);
                if done {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = S { g: graph, index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), on: BTreeSet::new(), next: 0, out: Vec::new() };
    for v in graph.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.out
}

/// The module graph of `src/`: module → the modules it names, with one example file per arrow.
fn module_graph() -> (BTreeMap<String, BTreeSet<String>>, BTreeMap<(String, String), String>) {
    let mut files = Vec::new();
    sources(&root().join("src"), &mut files);
    let modules: BTreeSet<String> = files.iter().filter_map(|p| module_of(p)).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = modules.iter().map(|m| (m.clone(), BTreeSet::new())).collect();
    let mut why = BTreeMap::new();
    for f in &files {
        let Some(m) = module_of(f) else { continue };
        let code = code_only(&std::fs::read_to_string(f).unwrap());
        for target in imports(&code) {
            if target != m && modules.contains(&target) {
                graph.get_mut(&m).unwrap().insert(target.clone());
                why.entry((m.clone(), target)).or_insert_with(|| f.strip_prefix(root()).unwrap().display().to_string());
            }
        }
    }
    (graph, why)
}

#[test]
fn the_checks_see_circles_and_group_imports() {
    let code = code_only("use crate::{a::X, b, c::{d, e}};\n// crate::z::q\nlet s = \"crate::y::w\"; crate::f::g();\n");
    let got: Vec<String> = imports(&code).into_iter().collect();
    assert_eq!(got, ["a", "b", "c", "f"]);
    let g: BTreeMap<String, BTreeSet<String>> = [
        ("a".to_string(), ["b".to_string()].into()),
        ("b".to_string(), ["c".to_string()].into()),
        ("c".to_string(), ["a".to_string()].into()),
        ("d".to_string(), ["a".to_string()].into()),
    ]
    .into();
    assert_eq!(circles(&g), vec![vec!["a".to_string(), "b".to_string(), "c".to_string()]]);
    let lens = function_lengths("fn f() {\n let s = \"}\";\n if x { y }\n}\nfn g() -> u8 { 1 }\n");
    assert_eq!(lens, vec![("f".to_string(), 1, 4), ("g".to_string(), 5, 1)]);
}

#[test]
fn no_import_circle_between_top_level_modules() {
    let (graph, why) = module_graph();
    let (graph, why) = (&graph, &why);
    let found = circles(graph);
    let described: Vec<String> = found
        .iter()
        .map(|c| {
            let arrows: Vec<String> = c
                .iter()
                .flat_map(|a| c.iter().filter(move |b| graph[a].contains(*b)).map(move |b| format!("{a} -> {b} ({})", why[&(a.clone(), b.clone())])))
                .collect();
            format!("circle {{{}}}: {}", c.join(", "), arrows.join("; "))
        })
        .collect();
    assert!(found.is_empty(), "import circles between top-level modules of src/:\n{}", described.join("\n"));
}

/// (name, first line, length in lines) of every `fn` with a body in `text`.
fn function_lengths(text: &str) -> Vec<(String, usize, usize)> {
    let code = code_only(text);
    let lines: Vec<&str> = code.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let t = line.trim_start();
        let Some(pos) = t.find("fn ") else { continue };
        let head = &t[..pos];
        let is_decl = head.split_whitespace().all(|w| matches!(w, "pub" | "const" | "async" | "unsafe" | "extern") || w.starts_with("pub("));
        if !is_decl || (pos > 0 && !head.ends_with(' ')) {
            continue;
        }
        let name: String = t[pos + 3..].chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
        // the body: from the first `{` after the signature (a `;` first: no body) to its match
        let mut depth = 0usize;
        let mut started = false;
        let mut end = None;
        'scan: for (j, l) in lines.iter().enumerate().skip(i) {
            let from = if j == i { pos } else { 0 };
            for ch in l[from..].chars() {
                match ch {
                    ';' if !started && depth == 0 => break 'scan,
                    '{' => {
                        started = true;
                        depth += 1;
                    }
                    '}' if started => {
                        depth -= 1;
                        if depth == 0 {
                            end = Some(j);
                            break 'scan;
                        }
                    }
                    _ => {}
                }
            }
        }
        if let Some(e) = end {
            out.push((name, i + 1, e - i + 1));
        }
    }
    out
}

/// The files docs/architecture.md lets run past the file limit: the `src/…` paths in backticks on
/// the lines of its "Long kernels" section.
fn long_kernels() -> Vec<String> {
    let doc = std::fs::read_to_string(root().join("docs/architecture.md")).unwrap_or_default();
    let mut inside = false;
    let mut out = Vec::new();
    for l in doc.lines() {
        if l.starts_with('#') {
            inside = l.to_ascii_lowercase().contains("long kernels");
            continue;
        }
        if inside {
            for part in l.split('`').skip(1).step_by(2) {
                if part.starts_with("src/") {
                    out.push(part.to_string());
                }
            }
        }
    }
    out
}

#[test]
fn no_file_over_900_lines_and_no_function_over_150() {
    let mut files = Vec::new();
    sources(&root().join("src"), &mut files);
    let allowed = long_kernels();
    let mut bad = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(root()).unwrap().display().to_string();
        let text = std::fs::read_to_string(f).unwrap();
        let n = text.lines().count();
        if n > MAX_FILE_LINES && !allowed.contains(&rel) {
            bad.push(format!("{rel}: {n} lines (limit {MAX_FILE_LINES}; a single-concern kernel may be named under \"Long kernels\" in docs/architecture.md)"));
        }
        for (name, line, len) in function_lengths(&text) {
            if len > MAX_FN_LINES {
                bad.push(format!("{rel}:{line}: fn {name} is {len} lines (limit {MAX_FN_LINES})"));
            }
        }
    }
    assert!(bad.is_empty(), "{} violations:\n{}", bad.len(), bad.join("\n"));
}

/// Every key a range check names as a literal (`check("time.end", …)`, `check_opt(…)`,
/// `check_in(TABLE, "…", …)`, `check_int("…", …)`, `lookup("…")`) has a row in a range table, so a
/// misspelt key fails here rather than as "internal: key … has no entry" when that path first runs.
#[test]
fn every_literal_range_key_has_a_table_row() {
    let mut tables = sinterdem::calibrate::every_table();
    tables.push(sinterdem::study::spec::RANGES);
    let mut files = Vec::new();
    sources(&root().join("src"), &mut files);
    let mut missing = Vec::new();
    let mut seen = 0;
    for f in &files {
        let whole = std::fs::read_to_string(f).unwrap();
        // the code, not its unit tests (which also name keys that must not exist)
        let text = whole.split("#[cfg(test)]").next().unwrap_or("");
        for call in ["check(\"", "check_opt(\"", "check_int(\"", "lookup(\"", "check_in(RANGES, \"", "check_in(super::RANGES, \""] {
            let mut rest = text;
            while let Some(i) = rest.find(call) {
                let before = rest[..i].chars().last();
                rest = &rest[i + call.len()..];
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
                    continue; // e.g. `study_check("` or `fn check("` in a doc
                }
                let key: String = rest.chars().take_while(|&c| c != '"').collect();
                if key.is_empty() || key.contains(' ') || key.contains('{') || !key.contains('.') {
                    continue;
                }
                seen += 1;
                if sinterdem::config::ranges::lookup_in(&tables, &key).is_none() {
                    missing.push(format!("{}: {key}", f.strip_prefix(root()).unwrap().display()));
                }
            }
        }
    }
    assert!(seen > 100, "only {seen} literal keys found: the scan is broken");
    // a file that checks through `config::check` (the shared keys only) names no key of another table
    for f in &files {
        let whole = std::fs::read_to_string(f).unwrap();
        let text = whole.split("#[cfg(test)]").next().unwrap_or("");
        let code = code_only(text);
        let local = code.contains("fn check(") || code.contains("fn check_opt(");
        let imports_shared = code.contains("config::check(")
            || code.contains("config::check_opt(")
            || code.lines().any(|l| {
                l.contains("use crate::config::") && (l.contains("check,") || l.contains("check}") || l.contains("check_opt") || l.contains("check as"))
            });
        let mut calls: Vec<String> = vec!["config::check(\"".into(), "config::check_opt(\"".into()];
        if imports_shared && !local {
            calls.extend(["check(\"".to_string(), "check_opt(\"".to_string()]);
        }
        if let Some(i) = code.find("check as ") {
            let alias: String = code[i + 9..].chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            calls.push(format!("{alias}(\""));
        }
        for call in &calls {
            let mut rest = text;
            while let Some(i) = rest.find(call.as_str()) {
                let before = rest[..i].chars().last();
                rest = &rest[i + call.len()..];
                if before.is_some_and(|c| c.is_alphanumeric() || c == '_') || (call.starts_with("check") && before == Some(':')) {
                    continue;
                }
                let key: String = rest.chars().take_while(|&c| c != '"').collect();
                if key.contains('.') && !key.contains('{') && sinterdem::config::ranges::lookup(&key).is_none() {
                    missing.push(format!("{}: {key} is checked against the shared table but is not in it", f.strip_prefix(root()).unwrap().display()));
                }
            }
        }
    }
    assert!(missing.is_empty(), "keys without a range-table row:\n{}", missing.join("\n"));
}
