//! Report-ready plots end to end (issue 25, item 7): a pair case, a small compact and two studies
//! write PNG and SVG plots whose text is the case title and its settings in plain words (no
//! equation numbers, no symbols, lengths in µm, time in min where it reads better), each series in
//! its own dash pattern, a study's second factor as one line per value and a `cases` study's
//! experiment ids as tick labels.

use sinterdem::kinds::{self, RunParams};
use sinterdem::study::{self, StudyOptions};
use std::path::{Path, PathBuf};

mod common;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn svg(path: &Path) -> String {
    let png = std::fs::read(path.with_extension("png")).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&png[1..4], b"PNG", "{}", path.display());
    std::fs::read_to_string(path.with_extension("svg")).unwrap()
}

/// The texts of an SVG (title, subtitle, labels, ticks, legend).
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text").skip(1).filter_map(|t| Some(t.split_once('>')?.1.split('<').next()?.trim().to_string())).collect()
}

/// The distinct `stroke-dasharray` values of an SVG.
fn dash_arrays(svg: &str) -> Vec<String> {
    let mut v: Vec<String> = svg.match_indices("stroke-dasharray=\"").map(|(i, _)| svg[i + 18..].split('"').next().unwrap().to_string()).collect();
    v.sort();
    v.dedup();
    v
}

fn assert_plain(file: &str, t: &[String]) {
    for text in t {
        for jargon in ["eq. ", "y1/R", "R_min", "dL/L0", "dL_bar", "Fig. 20", "_"] {
            assert!(!text.contains(jargon), "{file}: {text:?} has {jargon:?}");
        }
    }
}

#[test]
fn pair_plot_has_the_case_title_settings_plain_labels_and_two_line_styles() {
    let dir = common::tmp_dir("pair");
    let case = sinterdem::config::load_case(&repo().join("cases/pair-copper.toml"), &[]).unwrap();
    sinterdem::kinds::pair::run_pair_case(&case, &dir, false).unwrap();
    let s = svg(&dir.join("neck_shrinkage.svg"));
    let t = texts(&s);
    assert!(t.contains(&"copper pair, 1293 K: neck growth and shrinkage".to_string()), "{t:?}");
    assert!(t.contains(&"copper-ivannikov2022, two spheres of radius 25 µm, up to 1293 K, 83.3 min".to_string()), "{t:?}");
    assert!(t.contains(&"neck radius / smaller particle radius".to_string()));
    assert_plain("neck_shrinkage", &t);
    // neck ratio solid, shrinkage dashed: one dash array, on its line and its legend sample
    assert_eq!(dash_arrays(&s), ["10,9"]);
    assert_eq!(s.matches("stroke-dasharray=\"10,9\"").count(), 2);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn compact_plots_carry_the_case_title_and_read_in_plain_units() {
    let dir = common::tmp_dir("compact");
    let text = common::compact_text(&common::time_to(600.0), &[common::COPPER], &common::fcc(2), common::AT_1293_K);
    let case = common::case_value(&format!("title = \"fcc block\"\n{text}"), &[]);
    kinds::run(&case, &[], &dir, &RunParams { base_dir: dir.clone(), plots: true, ..Default::default() }).unwrap();
    for file in ["shrinkage", "relative_density", "coordination", "neck_ratio", "temperature", "layer_profile", "dl_bar_histogram"] {
        let s = svg(&dir.join(format!("{file}.svg")));
        let t = texts(&s);
        assert!(t.iter().any(|x| x.starts_with("fcc block: ")), "{file}: {t:?}");
        assert!(t.iter().any(|x| x.starts_with("32 particles of copper-ivannikov2022, mean radius 25 µm")), "{file}: {t:?}");
        assert_plain(file, &t);
        if !["layer_profile", "dl_bar_histogram", "neck_ratio"].contains(&file) {
            assert!(t.contains(&"time [min]".to_string()), "{file}: {t:?}");
        }
    }
    let t = texts(&svg(&dir.join("relative_density.svg")));
    assert!(t.contains(&"fcc block: relative density".to_string()), "{t:?}");
    let t = texts(&svg(&dir.join("layer_profile.svg")));
    assert!(t.contains(&"height above the bottom of the compact [µm]".to_string()), "{t:?}");
    // the mean-contact-shrinkage axis starts at zero: "0" is its lowest tick
    assert!(t.contains(&"0".to_string()), "{t:?}");
    // x, y and z shrinkage: solid, dashed and dotted; mean/min/max temperature likewise
    for file in ["shrinkage", "temperature"] {
        assert_eq!(dash_arrays(&svg(&dir.join(format!("{file}.svg")))), ["0.5,7", "10,9"], "{file}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn study_plots_show_the_ids_and_one_line_per_value_of_the_second_factor() {
    let dir = common::tmp_dir("study");
    let opts = StudyOptions { out: Some(dir.join("ti28")), ..Default::default() };
    study::run_study(&repo().join("cases/studies/titanium-28.toml"), &opts, &mut |_| {}).unwrap();
    let s = svg(&dir.join("ti28/plots/neck_ratio_vs_run.svg"));
    let t = texts(&s);
    for id in ["E1B", "E2B", "E14B", "E27B", "E28B"] {
        assert!(t.contains(&id.to_string()), "{id}: {t:?}");
    }
    assert!(!t.contains(&"27".to_string()), "run numbers instead of ids: {t:?}");
    assert!(t.contains(&"neck radius / smaller particle radius".to_string()), "{t:?}");
    assert!(t.contains(&"titanium 28 experiments: neck radius / smaller particle radius".to_string()), "{t:?}");
    let t = texts(&svg(&dir.join("ti28/plots/neck_ratio_at_1800s_vs_run.svg")));
    assert!(t.contains(&"neck radius / smaller particle radius at t = 30 min".to_string()), "{t:?}");
    // a grid: 3 radii × 2 peak temperatures of the E14B pair
    let case = repo().join("cases/titanium/E14B.toml");
    let text = format!(
        "title = \"E14B grid\"\nbase = \"{}\"\n[[parameters]]\nkey = \"pair.radius\"\nrange = [30e-6, 36e-6]\nnum = 3\n[[parameters]]\nkey = \"temperature.peak_temperature\"\nvalues = [1273.0, 1373.0]\n[collect]\nsummary = [\"shrinkage\"]\n",
        case.display()
    );
    std::fs::write(dir.join("grid.toml"), text).unwrap();
    let opts = StudyOptions { out: Some(dir.join("grid")), jobs: Some(2), ..Default::default() };
    study::run_study(&dir.join("grid.toml"), &opts, &mut |_| {}).unwrap();
    let s = svg(&dir.join("grid/plots/shrinkage_vs_pair.radius.svg"));
    let t = texts(&s);
    assert!(t.contains(&"radius [µm]".to_string()), "{t:?}");
    for v in ["peak temperature = 1273.0 K", "peak temperature = 1373.0 K"] {
        assert!(t.contains(&v.to_string()), "{v}: {t:?}");
    }
    assert_eq!(dash_arrays(&s), ["10,9"], "two lines: solid and dashed");
    let t = texts(&svg(&dir.join("grid/plots/shrinkage_vs_temperature.peak_temperature.svg")));
    assert!(t.contains(&"peak temperature [K]".to_string()), "{t:?}");
    for v in ["radius = 30 µm", "radius = 33 µm", "radius = 36 µm"] {
        assert!(t.contains(&v.to_string()), "{v}: {t:?}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn titanium_table_plot_has_one_line_per_schedule_from_zero() {
    let dir = common::tmp_dir("titanium");
    sinterdem::kinds::titanium::run_all_titanium(&dir, sinterdem::kinds::titanium::TRUNCATED_START, None).unwrap();
    let s = svg(&dir.join("titanium_shrinkage.svg"));
    let t = texts(&s);
    assert!(t.contains(&"Titanium pairs of Ivannikov et al. 2022 (Table 3): final shrinkage".to_string()), "{t:?}");
    assert!(t.contains(&"hold time at the peak temperature [min]".to_string()), "{t:?}");
    for g in ["1203 K, 20 K/min", "1203 K, 50 K/min", "1373 K, 20 K/min", "1373 K, 50 K/min", "1573 K, 20 K/min", "1573 K, 50 K/min"] {
        assert!(t.contains(&g.to_string()), "{g}: {t:?}");
    }
    // six lines in the four styles: three dash arrays
    assert_eq!(dash_arrays(&s), ["0.5,7", "10,9", "12,8,0.5,8"]);
    assert!(t.contains(&"0".to_string()), "the shrinkage axis starts at zero: {t:?}");
    if std::env::var_os("SINTERDEM_KEEP_PLOTS").is_none() {
        std::fs::remove_dir_all(&dir).ok();
    }
}
