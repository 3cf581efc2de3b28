//! The documentation stays true: the generated key table matches the code's range tables, and
//! every TOML snippet in docs/ parses (heat cases among them also pass validation).

use std::path::Path;

#[test]
fn case_file_reference_lists_every_numeric_key() {
    let doc = std::fs::read_to_string("docs/case-file.md").unwrap();
    let begin = doc.find("<!-- keys:begin").expect("marker");
    let body_start = doc[begin..].find('\n').unwrap() + begin + 1;
    let end = doc.find("<!-- keys:end -->").expect("marker");
    assert_eq!(
        &doc[body_start..end],
        sinterdem::config::ranges::markdown(&sinterdem::calibrate::every_table()),
        "docs/case-file.md is out of date: regenerate with `sinterdem keys`"
    );
}

#[test]
fn study_file_reference_lists_every_numeric_key() {
    let doc = std::fs::read_to_string("docs/studies.md").unwrap();
    let begin = doc.find("<!-- keys:begin").expect("marker");
    let body_start = doc[begin..].find('\n').unwrap() + begin + 1;
    let end = doc.find("<!-- keys:end -->").expect("marker");
    assert_eq!(&doc[body_start..end], sinterdem::study::spec::markdown(), "docs/studies.md is out of date: regenerate with `sinterdem keys --study`");
}

#[test]
fn toml_snippets_in_docs_parse() {
    let mut count = 0;
    for entry in std::fs::read_dir("docs").unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("md") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let mut rest = text.as_str();
        while let Some(i) = rest.find("```toml\n") {
            let body = &rest[i + 8..];
            let j = body.find("```").expect("unterminated snippet");
            let snippet = &body[..j];
            let value: toml::Table = snippet.parse().unwrap_or_else(|e| panic!("{}: TOML snippet does not parse: {e}\n{snippet}", path.display()));
            let v = toml::Value::Table(value);
            let is_heat_case = v.get("time").is_some() && v.get("particles").is_some() && v.get("kind").is_none();
            if is_heat_case {
                sinterdem::scene::prepare(v, Path::new("cases")).unwrap_or_else(|e| panic!("{}: heat snippet rejected: {e}", path.display()));
            }
            count += 1;
            rest = &body[j + 3..];
        }
    }
    assert!(count >= 1);
}

/// The repository is self-contained: nothing under docs/, src/, tests/, validation/, cases/ or
/// README.md cites the design notes the project started from (they are not part of the repository;
/// docs/references.md says where their content lives now), and every `docs/X.md` named in docs/
/// and README.md exists.
#[test]
fn docs_are_self_contained_and_their_links_resolve() {
    // the file names of the design notes, and paths into the folder that held them
    let forbidden = [
        "seven-dof-model.md",
        "heat-network.md",
        "architecture.md",
        "bonded-mechanics.md",
        "explicit-sintering-laws.md",
        "explicit-laws.md",
        "stack.md",
        "../shared",
        "/work/shared",
    ];
    fn walk(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if matches!(path.extension().and_then(|e| e.to_str()), Some("md" | "rs" | "py" | "toml" | "csv" | "sh" | "txt" | "json")) {
                out.push(path);
            }
        }
    }
    let mut files = vec![std::path::PathBuf::from("README.md")];
    for dir in ["docs", "src", "tests", "validation", "cases"] {
        walk(Path::new(dir), &mut files);
    }
    let mut bad = Vec::new();
    for f in &files {
        let Ok(text) = std::fs::read_to_string(f) else { continue };
        for (n, line) in text.lines().enumerate() {
            // this test names the forbidden strings itself
            if f.ends_with("tests/docs.rs") && forbidden.iter().any(|s| line.trim_start().starts_with(&format!("\"{s}\""))) {
                continue;
            }
            for s in forbidden {
                // a doc of ours with the same name as a design note is cited as `docs/NAME`
                let ours = Path::new("docs").join(s).is_file();
                let cited = if ours { line.replace(&format!("docs/{s}"), "").contains(s) } else { line.contains(s) };
                if cited {
                    bad.push(format!("{}:{}: cites `{s}`", f.display(), n + 1));
                }
            }
        }
    }
    assert!(files.len() > 50, "walked only {} files", files.len());
    assert!(bad.is_empty(), "citations of files that are not in the repository (cite docs/… or a paper by author and year):\n{}", bad.join("\n"));

    // every docs/X.md named in docs/ and README.md exists
    let mut missing = Vec::new();
    let mut links = 0;
    let doc_files: Vec<_> =
        files.iter().filter(|f| f.starts_with("docs") || f.ends_with("README.md")).filter(|f| f.extension().and_then(|e| e.to_str()) == Some("md")).collect();
    for f in doc_files {
        let text = std::fs::read_to_string(f).unwrap();
        let mut rest = text.as_str();
        while let Some(i) = rest.find("docs/") {
            let tail = &rest[i + 5..];
            let name: String = tail.chars().take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')).collect();
            if let Some(stem) = name.strip_suffix(".md").or_else(|| name.split_once(".md").map(|(s, _)| s)) {
                links += 1;
                let target = Path::new("docs").join(format!("{stem}.md"));
                if !target.is_file() {
                    missing.push(format!("{}: docs/{stem}.md", f.display()));
                }
            }
            rest = &tail[name.len()..];
        }
    }
    assert!(links > 20, "found only {links} docs/ links");
    assert!(missing.is_empty(), "links to missing docs:\n{}", missing.join("\n"));
}
