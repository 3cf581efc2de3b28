//! Bundled packing cases (slow ones are ignored; run with `--ignored`).
use std::path::Path;

fn load(name: &str) -> toml::Value {
    sinterdem::config::load_case(&Path::new(env!("CARGO_MANIFEST_DIR")).join("cases").join(name), &[]).unwrap()
}

#[test]
#[ignore]
fn print_copper() {
    let out = std::env::temp_dir().join("sinterdem-green-copper");
    let s = sinterdem::packing::generate_case(&load("green-copper.toml"), &out, true);
    println!("{s:#?}");
}

#[test]
#[ignore]
fn print_titanium() {
    let out = std::env::temp_dir().join("sinterdem-green-titanium");
    let s = sinterdem::packing::generate_case(&load("green-titanium.toml"), &out, true);
    println!("{s:#?}");
}

#[test]
fn bundled_cases_pass_the_check() {
    for name in ["green-copper.toml", "green-titanium.toml"] {
        sinterdem::packing::check_generate_case(&load(name)).unwrap();
    }
}
