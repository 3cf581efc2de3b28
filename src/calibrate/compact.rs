//! `--validate-compact`: the pair-calibrated material on a packing (docs/calibration.md, "From
//! pairs to a packing"). Each chosen experiment's schedule runs on the compact case named in
//! `[compact]`, with the fitted diffusion data written into its material, as one study (local
//! engine, resumable); `compact_validation.csv` sets the compact's shrinkage beside the measured
//! one and the pair's.

use super::data::Experiment;
use super::forward::Prediction;
use crate::error::{ConfigError, Error, IoError, ModelError};
use crate::models::diffusion7::Material;
use crate::study::{self, StudyOptions};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// `[compact]` of a calibration file.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompactSection {
    /// A compact case (`kind = "compact"`, `thermal.mode = "isothermal"`), relative to the
    /// calibration file.
    pub case: Option<String>,
    /// Experiment ids to run (default: all).
    #[serde(default)]
    pub experiments: Vec<String>,
    /// Overrides of the compact case (`key.path=value`), e.g. to shorten it.
    #[serde(default)]
    pub overrides: Vec<String>,
}

/// Writes the derived compact case (fitted material, schedule placeholder) into `dir`.
fn derived_case(case_path: &Path, material: &Material, overrides: &[String]) -> Result<toml::Value, Error> {
    let mut case = crate::config::load_case(case_path, &[])?;
    let base = case_path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let at = |m: &str| ConfigError::invalid(format!("[compact] case = {}: {m}", case_path.display()));
    if case.get("kind").and_then(|k| k.as_str()) != Some("compact") {
        return Err(at("needs kind = \"compact\"").into());
    }
    let mode = case.get("thermal").and_then(|t| t.get("mode")).and_then(|m| m.as_str()).unwrap_or("");
    if mode != "isothermal" {
        return Err(at("needs thermal.mode = \"isothermal\": each experiment's schedule replaces the furnace profile").into());
    }
    // the packing file, absolute (the derived case lives elsewhere)
    if let Some(f) = case.get_mut("particles").and_then(|p| p.get_mut("file"))
        && let Some(s) = f.as_str()
        && Path::new(s).is_relative()
    {
        *f = toml::Value::String(base.join(s).to_string_lossy().to_string());
    }
    let mats = case.get_mut("materials").and_then(|m| m.as_array_mut()).ok_or_else(|| at("has no [[materials]]"))?;
    let names: Vec<String> = mats.iter().filter_map(|m| m.get("name").and_then(|n| n.as_str()).map(String::from)).collect();
    let entry = mats
        .iter_mut()
        .find(|m| m.get("name").and_then(|n| n.as_str()) == Some(material.name.as_str()))
        .and_then(|m| m.as_table_mut())
        .ok_or_else(|| at(&format!("has no material named \"{}\" (it has: {})", material.name, names.join(", "))))?;
    let phases = toml::Value::try_from(&material.phases).map_err(|e| at(&format!("fitted phases: {e}")))?;
    entry.insert("phases".into(), phases);
    entry.insert("calibrated_min_temperature".into(), toml::Value::Float(material.calibrated_min_temperature));
    entry.insert("calibrated_max_temperature".into(), toml::Value::Float(material.calibrated_max_temperature));
    entry.insert("source".into(), toml::Value::String(material.source.clone()));
    if let Some(tm) = material.melting_temperature {
        entry.insert("melting_temperature".into(), toml::Value::Float(tm));
    }
    let mut profile = toml::Table::new();
    profile.insert("schedule".into(), toml::Value::String("start 293 K".into()));
    let thermal = case.get_mut("thermal").and_then(|t| t.as_table_mut()).ok_or_else(|| at("has no [thermal]"))?;
    let furnace = thermal.entry("furnace").or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let furnace = furnace.as_table_mut().ok_or_else(|| at("thermal.furnace is not a table"))?;
    furnace.insert("profile".into(), toml::Value::Table(profile));
    for o in overrides {
        crate::config::apply_override(&mut case, o)?;
    }
    Ok(case)
}

/// Runs the chosen experiments on the compact and writes `compact_validation.csv`.
#[allow(clippy::too_many_arguments)]
pub fn validate(
    section: &CompactSection,
    calib_dir: &Path,
    material: &Material,
    experiments: &[Experiment],
    predictions: &[Result<Prediction, ModelError>],
    out: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<PathBuf, Error> {
    let case_rel =
        section.case.as_ref().ok_or_else(|| ConfigError::invalid("--validate-compact needs [compact] case = \"compact.toml\" in the calibration file"))?;
    let case_path = calib_dir.join(case_rel);
    let chosen: Vec<usize> = if section.experiments.is_empty() {
        (0..experiments.len()).collect()
    } else {
        section
            .experiments
            .iter()
            .map(|id| {
                experiments.iter().position(|e| &e.id == id).ok_or_else(|| {
                    ConfigError::invalid(format!(
                        "[compact] experiments: no experiment \"{id}\" in the data (it has: {})",
                        experiments.iter().map(|e| e.id.as_str()).collect::<Vec<_>>().join(", ")
                    ))
                })
            })
            .collect::<Result<_, _>>()?
    };
    let dir = out.join("compact");
    crate::io::ensure_dir(&dir)?;
    let case = derived_case(&case_path, material, &section.overrides)?;
    let case_file = dir.join("case.toml");
    let text = toml::to_string(&case).map_err(|e| IoError::new(&case_file, e))?;
    std::fs::write(&case_file, format!("# {} with the pair-calibrated material (sinterdem calibrate --validate-compact)\n{text}", case_path.display()))
        .map_err(|e| IoError::new(&case_file, e))?;
    let list = |f: &dyn Fn(&Experiment) -> String| chosen.iter().map(|&i| f(&experiments[i])).collect::<Vec<_>>().join(", ");
    let q = |s: &str| toml::Value::String(s.to_string()).to_string();
    let study_text = format!(
        "title = \"compact validation\"\nbase = \"case.toml\"\n[design]\nkind = \"zip\"\n\
         [[parameters]]\nkey = \"title\"\nname = \"id\"\nvalues = [{}]\n\
         [[parameters]]\nkey = \"thermal.furnace.profile.schedule\"\nname = \"schedule\"\nvalues = [{}]\n\
         [[parameters]]\nkey = \"time.end\"\nname = \"end_s\"\nvalues = [{}]\n\
         [collect]\nsummary = [\"shrinkage_x\", \"shrinkage_y\", \"shrinkage_z\", \"relative_density\", \"neck_ratio\", \"completed\"]\n",
        list(&|e| q(&e.id)),
        list(&|e| q(&e.schedule)),
        list(&|e| format!("{:?}", e.profile.duration()))
    );
    let study_file = dir.join("study.toml");
    std::fs::write(&study_file, study_text).map_err(|e| IoError::new(&study_file, e))?;
    log(&format!("validate-compact: {} experiment(s) on {} ({})", chosen.len(), case_path.display(), study_file.display()));
    let opts = StudyOptions { out: Some(dir.join("study")), progress: true, ..Default::default() };
    let info = study::run_study(&study_file, &opts, log)?;
    let (_, _, plan) = study::prepare(&study_file, &opts)?;
    let mut csv = String::from(
        "id,measured_shrinkage,measured_shrinkage_sigma,pair_shrinkage,compact_shrinkage_mean,compact_shrinkage_x,compact_shrinkage_y,compact_shrinkage_z,compact_relative_density,compact_neck_ratio,status,error\n",
    );
    for (k, run) in plan.iter().enumerate() {
        let e = &experiments[chosen[k]];
        let rec = study::store::read_record(&info.dir, run);
        let s = rec.as_ref().map(|r| &r.summary);
        let f = |key: &str| s.and_then(|s| s[key].as_f64());
        let sh = [f("shrinkage_x"), f("shrinkage_y"), f("shrinkage_z")];
        let mean = if sh.iter().all(Option::is_some) { Some(sh.iter().flatten().sum::<f64>() / 3.0) } else { None };
        let cell = |v: Option<f64>| v.map(|x| format!("{x:?}")).unwrap_or_default();
        let meas = e.end.shrinkage;
        let pair = predictions.get(chosen[k]).and_then(|p| p.as_ref().ok()).map(|p| p.end.shrinkage);
        let (status, err) = match &rec {
            Some(r) => (r.status.clone(), r.error.clone().unwrap_or_default()),
            None => ("missing".into(), String::new()),
        };
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{}\n",
            crate::io::csv_text(&e.id),
            cell(meas.map(|m| m.value)),
            cell(meas.map(|m| m.sigma)),
            cell(pair),
            cell(mean),
            cell(sh[0]),
            cell(sh[1]),
            cell(sh[2]),
            cell(f("relative_density")),
            cell(f("neck_ratio")),
            status,
            crate::io::csv_text(&err)
        ));
        log(&format!(
            "  {}: measured shrinkage {}, pair {}, compact {} (x/y/z {}/{}/{})",
            e.id,
            cell(meas.map(|m| m.value)),
            cell(pair),
            cell(mean),
            cell(sh[0]),
            cell(sh[1]),
            cell(sh[2])
        ));
    }
    let path = out.join("compact_validation.csv");
    std::fs::write(&path, csv).map_err(|e| IoError::new(&path, e))?;
    Ok(path)
}
