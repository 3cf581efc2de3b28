//! The documentation stays true: the generated key table matches the code's range tables, and
//! every TOML snippet in docs/ parses (heat cases among them also pass validation).

use std::path::Path;

#[test]
fn case_file_reference_lists_every_numeric_key() {
    let doc = std::fs::read_to_string("docs/case-file.md").unwrap();
    let begin = doc.find("<!-- keys:begin").expect("marker");
    let body_start = doc[begin..].find('\n').unwrap() + begin + 1;
    let end = doc.find("<!-- keys:end -->").expect("marker");
    assert_eq!(&doc[body_start..end], sinterdem::config::ranges::markdown(), "docs/case-file.md is out of date: regenerate with `sinterdem keys`");
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
                sinterdem::heat::run::prepare(v, Path::new("cases")).unwrap_or_else(|e| panic!("{}: heat snippet rejected: {e}", path.display()));
            }
            count += 1;
            rest = &body[j + 3..];
        }
    }
    assert!(count >= 1);
}
