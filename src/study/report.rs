//! Gathering a study: `DIR/study.csv` (one row per run, plain header), `DIR/study.json` and a
//! PNG per output against each numeric parameter (`DIR/plots/`). Gathering reads only the result
//! records and series files, so it gives the same bytes whichever engine ran the runs (apart from
//! the `wall_seconds` column).

use super::spec::{Study, Values};
use super::store::{self, PlannedRun, RunRecord};
use crate::error::{Error, IoError};
use crate::plot::{Plot, Series};
use serde_json::{Value, json};
use std::path::Path;

/// One gathered row.
#[derive(Debug, Clone)]
pub struct Row {
    pub run: PlannedRun,
    pub record: Option<RunRecord>,
    /// Output column → cell text (empty: not available).
    pub outputs: Vec<(String, String)>,
}

/// Counts of a gathered study.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    pub runs: usize,
    pub ok: usize,
    pub failed: usize,
    pub missing: usize,
}

fn number_text(v: &Value) -> String {
    match v {
        Value::Null => String::new(),
        Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() => format!("{x:?}"),
            _ => n.to_string(),
        },
        Value::String(s) => s.clone(),
        Value::Bool(b) => b.to_string(),
        other => other.to_string(),
    }
}

/// Reads a series CSV (`#` lines skipped, first other line the header) into (header, rows).
pub fn read_series(path: &Path) -> Option<(Vec<String>, Vec<Vec<f64>>)> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut lines = text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let header: Vec<String> = lines.next()?.split(',').map(|s| s.trim().to_string()).collect();
    let rows = lines.map(|l| l.split(',').map(|v| v.trim().parse().unwrap_or(f64::NAN)).collect()).collect();
    Some((header, rows))
}

/// Linear interpolation of column `col` at time `t` [s] (time = first column); None outside the
/// recorded interval.
pub fn interpolate(rows: &[Vec<f64>], col: usize, t: f64) -> Option<f64> {
    let first = rows.first()?;
    let last = rows.last()?;
    if t < first[0] || t > last[0] {
        return None;
    }
    let k = rows.partition_point(|r| r[0] < t);
    if k == 0 {
        return rows[0].get(col).copied();
    }
    let (a, b) = (&rows[k - 1], &rows[k.min(rows.len() - 1)]);
    let (ya, yb) = (*a.get(col)?, *b.get(col)?);
    if b[0] == a[0] {
        return Some(yb);
    }
    Some(ya + (yb - ya) * (t - a[0]) / (b[0] - a[0]))
}

/// The output columns of the study and each row's cells.
pub fn gather(study: &Study, dir: &Path, plan: &[PlannedRun]) -> Vec<Row> {
    use rayon::prelude::*;
    let records: Vec<Option<RunRecord>> = plan.par_iter().map(|r| store::read_record(dir, r)).collect();
    // an array-valued summary key expands to KEY.0, KEY.1, … up to the longest array
    let widths: Vec<Option<usize>> = study
        .collect_summary
        .iter()
        .map(|k| records.iter().flatten().filter_map(|r| crate::kinds::lookup(&r.summary, k)).filter_map(|v| v.as_array().map(Vec::len)).max())
        .collect();
    plan.par_iter()
        .zip(records)
        .map(|(run, record)| {
            let mut outputs = Vec::new();
            for (k, w) in study.collect_summary.iter().zip(&widths) {
                let v = record.as_ref().and_then(|r| crate::kinds::lookup(&r.summary, k));
                match w {
                    Some(n) => {
                        for i in 0..*n {
                            let cell = v.and_then(|v| v.get(i)).map(number_text).unwrap_or_default();
                            outputs.push((format!("{k}.{i}"), cell));
                        }
                    }
                    None => outputs.push((k.clone(), v.map(number_text).unwrap_or_default())),
                }
            }
            let series = record.as_ref().filter(|r| r.ok()).and_then(|_| read_series(&store::run_dir(dir, run.index).join("series.csv")));
            for s in &study.collect_series {
                let col = series.as_ref().and_then(|(h, _)| h.iter().position(|c| *c == s.column));
                for &t in &s.times {
                    let v = match (&series, col) {
                        (Some((_, rows)), Some(c)) => interpolate(rows, c, t).filter(|x| x.is_finite()).map(|x| format!("{x:?}")).unwrap_or_default(),
                        _ => String::new(),
                    };
                    outputs.push((format!("{}_at_{t}s", s.column), v));
                }
            }
            Row { run: run.clone(), record, outputs }
        })
        .collect()
}

/// Counts ok, failed and missing runs.
pub fn counts(rows: &[Row]) -> Counts {
    let mut c = Counts { runs: rows.len(), ..Default::default() };
    for r in rows {
        match &r.record {
            Some(rec) if rec.ok() => c.ok += 1,
            Some(_) => c.failed += 1,
            None => c.missing += 1,
        }
    }
    c
}

/// Writes study.csv, study.json and (with `plots`) the plots; returns the counts.
pub fn write(study: &Study, dir: &Path, rows: &[Row], plots: bool) -> Result<Counts, Error> {
    let mut header: Vec<String> = vec!["run".into()];
    if study.case_column {
        header.push("case".into());
    }
    header.extend(study.parameters.iter().map(|p| p.name.clone()));
    if let Some(r) = rows.first() {
        header.extend(r.outputs.iter().map(|o| o.0.clone()));
    }
    header.extend(["status", "error", "wall_seconds"].map(String::from));
    let mut csv = header.iter().map(|h| crate::io::csv_text(h)).collect::<Vec<_>>().join(",") + "\n";
    let mut runs_json = Vec::new();
    for r in rows {
        let mut cells = vec![r.run.index.to_string()];
        if study.case_column {
            cells.push(r.run.case_label.clone());
        }
        cells.extend(r.run.parameters.iter().map(|p| p.1.clone()));
        cells.extend(r.outputs.iter().map(|o| o.1.clone()));
        let (status, error, wall) = match &r.record {
            Some(rec) => (rec.status.clone(), rec.error.clone().unwrap_or_default(), format!("{:.6}", rec.wall_seconds)),
            None => ("missing".into(), String::new(), String::new()),
        };
        cells.push(status.clone());
        cells.push(error.clone());
        cells.push(wall);
        csv.push_str(&(cells.iter().map(|c| crate::io::csv_text(c)).collect::<Vec<_>>().join(",") + "\n"));
        runs_json.push(json!({
            "run": r.run.index,
            "case": r.run.case_path,
            "parameters": r.run.parameters.iter().map(|p| (p.0.clone(), Value::String(p.1.clone()))).collect::<serde_json::Map<_, _>>(),
            "overrides": r.run.overrides,
            "hash": r.run.hash,
            "dir": format!("runs/{:04}", r.run.index),
            "status": status,
            "error": r.record.as_ref().and_then(|x| x.error.clone()),
            "outputs": r.outputs.iter().map(|o| (o.0.clone(), o.1.parse::<f64>().ok().filter(|x| x.is_finite()).map(Value::from).unwrap_or_else(|| if o.1.is_empty() { Value::Null } else { Value::String(o.1.clone()) }))).collect::<serde_json::Map<_, _>>(),
            "wall_seconds": r.record.as_ref().map(|x| x.wall_seconds),
        }));
    }
    store::write_atomic(&dir.join("study.csv"), &csv)?;
    let c = counts(rows);
    let j = json!({"title": study.title, "study_file": study.path, "counts": c, "runs": runs_json});
    store::write_atomic(&dir.join("study.json"), &serde_json::to_string_pretty(&j).map_err(|e| IoError::new(dir.join("study.json"), e))?)?;
    if plots && let Err(e) = write_plots(study, dir, rows) {
        crate::plot::warn_not_written(&e);
    }
    Ok(c)
}

/// A PNG per numeric output against each numeric parameter ([`study_plots`]).
fn write_plots(study: &Study, dir: &Path, rows: &[Row]) -> Result<(), Error> {
    let pdir = dir.join("plots");
    crate::io::ensure_dir(&pdir)?;
    for (file, p) in study_plots(study, rows) {
        p.save_png(&pdir.join(file))?;
    }
    Ok(())
}

/// A plain-language axis label of a study column or parameter: a name a reader knows and the
/// unit, from a short dictionary of the summary keys and series columns, the unit suffix of the
/// name (`_K`, `_s`, `_m`, `_Pa`, …) or the parameter's key (`…q_gb` in J/mol, `…d0_surface` in
/// m²/s); `neck_ratio_at_1800s` reads "neck radius / smaller particle radius at t = 30 min".
/// Returns (name, unit; empty: dimensionless).
pub fn plain_name(column: &str, key: Option<&str>) -> (String, String) {
    if let Some((col, t)) = column.rsplit_once("_at_").and_then(|(c, t)| Some((c, t.strip_suffix('s')?.parse::<f64>().ok()?))) {
        let (n, u) = plain_name(col, None);
        return (format!("{n} at t = {}", crate::plot::fmt_time(t)), u);
    }
    let known: &[(&str, &str, &str)] = &[
        ("neck_ratio", "neck radius / smaller particle radius", ""),
        ("neck_ratio_mean", "mean neck radius / smaller particle radius", ""),
        ("shrinkage", "shrinkage", ""),
        ("shrinkage_x", "shrinkage along x", ""),
        ("shrinkage_y", "shrinkage along y", ""),
        ("shrinkage_z", "shrinkage along z", ""),
        ("relative_density", "relative density", ""),
        ("coordination_mean", "mean contacts per particle", ""),
        ("contacts", "contacts", ""),
        ("steps", "time steps", ""),
        ("rhs_evaluations", "model evaluations", ""),
        ("volume_drift_rel", "relative volume drift", ""),
        ("wall_seconds", "wall time", "s"),
        ("detect_new", "new-contact detection", ""),
        ("final_time_s", "simulated time", "s"),
    ];
    let last = column.rsplit('.').next().unwrap_or(column);
    if let Some(&(_, n, u)) = known.iter().find(|k| k.0 == column || k.0 == last) {
        return (n.to_string(), u.to_string());
    }
    let suffixes: &[(&str, &str)] = &[("_W_per_mK", "W/(m K)"), ("_K", "K"), ("_s", "s"), ("_m", "m"), ("_Pa", "Pa"), ("_N", "N"), ("_J", "J")];
    let (stem, mut unit) = suffixes.iter().find_map(|(s, u)| column.strip_suffix(s).map(|st| (st, u.to_string()))).unwrap_or((column, String::new()));
    let k = key.map(|k| k.rsplit('.').next().unwrap_or(k)).unwrap_or(stem);
    let what = |w: &str| match w {
        "gb" => "grain-boundary",
        "surface" => "surface",
        "lattice" => "lattice",
        _ => "",
    };
    let mut words: Vec<String> = stem.rsplit('.').next().unwrap_or(stem).split('_').map(str::to_string).collect();
    if let Some((kind, path)) = k.split_once('_') {
        let path = what(path);
        let named = match kind {
            "d0" if !path.is_empty() => Some((format!("{path} diffusion D0"), "m²/s")),
            "q" if !path.is_empty() => Some((format!("{path} activation energy"), "J/mol")),
            "delta" if !path.is_empty() => Some((format!("{path} layer thickness"), "m")),
            "gamma" if !path.is_empty() => Some((format!("{path} energy"), "J/m²")),
            _ => None,
        };
        if let Some((n, u)) = named {
            // a prefix of the column name before the key's own words (`beta_`) names the phase
            let prefix = stem.strip_suffix(k).map(|p| p.trim_end_matches('_')).filter(|p| !p.is_empty());
            words = match prefix {
                Some(p) => vec![format!("{}-phase {n}", p.replace('_', " "))],
                None => vec![n],
            };
            unit = u.to_string();
        }
    }
    if unit.is_empty() && (k.ends_with("temperature") || k == "constant") {
        unit = "K".into();
    }
    if unit.is_empty() && (k == "radius" || k.ends_with("_radius")) {
        unit = "m".into();
    }
    (words.join(" "), unit)
}

/// A label with its unit: `temperature [K]`, `shrinkage`.
fn with_unit(name: &str, unit: &str) -> String {
    if unit.is_empty() { name.to_string() } else { format!("{name} [{unit}]") }
}

/// Values in metres read in µm (or mm, nm): the converted points and the label's unit.
fn readable(pts: Vec<(f64, f64)>, unit: &str, x: bool) -> (Vec<(f64, f64)>, String) {
    if unit != "m" {
        return (pts, unit.to_string());
    }
    let span = pts.iter().map(|p| if x { p.0.abs() } else { p.1.abs() }).fold(0.0, f64::max);
    let u = crate::plot::length_unit(span);
    (pts.into_iter().map(|(a, b)| if x { (u.of(a), b) } else { (a, u.of(b)) }).collect(), u.name.to_string())
}

/// The plots of a gathered study (file name, plot): each numeric output against each numeric
/// parameter, one line per value of a second factor when the study has one with 2 to 8 values
/// (a grid), markers at every run and the axes padded so none is cut; without a numeric
/// parameter (a `cases` study) against the runs, the case names (E1B … E28B) as tick labels.
/// Axis labels in plain words with units ([`plain_name`]).
pub fn study_plots(study: &Study, rows: &[Row]) -> Vec<(String, Plot)> {
    let ok: Vec<&Row> = rows.iter().filter(|r| r.record.as_ref().is_some_and(RunRecord::ok)).collect();
    let Some(first) = ok.first() else { return Vec::new() };
    let numeric = |s: &str| s.parse::<f64>().ok().filter(|x| x.is_finite());
    let distinct = |i: usize| -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for r in &ok {
            let s = &r.run.parameters[i].1;
            if !v.contains(s) {
                v.push(s.clone());
            }
        }
        v
    };
    let np = study.parameters.len();
    let mut out = Vec::new();
    let n_ok = ok.len();
    // x axes: numeric parameters, else the runs by name
    let mut axes: Vec<Option<usize>> = (0..np).filter(|&i| ok.iter().all(|r| numeric(&r.run.parameters[i].1).is_some())).map(Some).collect();
    if axes.is_empty() {
        axes.push(None);
    }
    for (k, (name, _)) in first.outputs.iter().enumerate() {
        let (yname, yunit) = plain_name(name, None);
        for &axis in &axes {
            let y_of = |r: &Row| numeric(&r.outputs[k].1);
            let (mut p, groups, xfile): (Plot, Vec<(String, Vec<(f64, f64)>)>, String) = match axis {
                Some(i) => {
                    let par = &study.parameters[i];
                    let log = matches!(par.values, Values::Range { log: true, .. } | Values::Bounds { log: true, .. });
                    let (xname, xunit) = plain_name(&par.name, Some(&par.key));
                    let grid = distinct(i).len() < n_ok;
                    let g = (0..np).find(|&j| j != i && grid && (2..=8).contains(&distinct(j).len()));
                    let pts_of = |filter: &dyn Fn(&Row) -> bool| -> Vec<(f64, f64)> {
                        let mut v: Vec<(f64, f64)> =
                            ok.iter().filter(|r| filter(r)).filter_map(|r| Some((numeric(&r.run.parameters[i].1)?, y_of(r)?))).collect();
                        v.sort_by(|a, b| a.0.total_cmp(&b.0));
                        v
                    };
                    let groups: Vec<(String, Vec<(f64, f64)>)> = match g {
                        Some(j) => {
                            let (gname, gunit) = plain_name(&study.parameters[j].name, Some(&study.parameters[j].key));
                            distinct(j)
                                .into_iter()
                                .map(|v| {
                                    let label = match (gunit.as_str(), numeric(&v)) {
                                        ("", _) => format!("{gname}: {v}"),
                                        ("m", Some(x)) => format!("{gname} = {}", crate::plot::fmt_length(x)),
                                        (u, _) => format!("{gname} = {v} {u}"),
                                    };
                                    (label, pts_of(&|r: &Row| r.run.parameters[j].1 == v))
                                })
                                .collect()
                        }
                        None => vec![(format!("{} runs", n_ok), pts_of(&|_: &Row| true))],
                    };
                    let (groups, xunit) = {
                        let mut unit = xunit.clone();
                        let gs = groups
                            .into_iter()
                            .map(|(l, pts)| {
                                let (pts, u) = readable(pts, &xunit, true);
                                unit = u;
                                (l, pts)
                            })
                            .collect();
                        (gs, unit)
                    };
                    let by =
                        g.map(|j| format!("; one line per {}", plain_name(&study.parameters[j].name, Some(&study.parameters[j].key)).0)).unwrap_or_default();
                    let p = Plot::new(format!("{}: {yname} against {xname}", study.title))
                        .subtitle(format!("{} runs of {}{by}", n_ok, rows.len()))
                        .labels(with_unit(&xname, &xunit) + if log { " (log scale)" } else { "" }, "")
                        .log_x(log);
                    (p, groups, sanitize(&par.name))
                }
                None => {
                    let ticks: Vec<(f64, String)> = rows
                        .iter()
                        .map(|r| ((r.run.index + 1) as f64, if study.case_column { r.run.case_label.clone() } else { format!("run {}", r.run.index) }))
                        .collect();
                    let pts: Vec<(f64, f64)> = ok.iter().filter_map(|r| Some(((r.run.index + 1) as f64, y_of(r)?))).collect();
                    let p = Plot::new(format!("{}: {yname}", study.title))
                        .subtitle(format!("{} runs of {}, in study order", n_ok, rows.len()))
                        .labels(if study.case_column { "case" } else { "run" }, "")
                        .x_ticks(ticks);
                    (p, vec![(format!("{n_ok} runs"), pts)], "run".to_string())
                }
            };
            let all: Vec<(f64, f64)> = groups.iter().flat_map(|g| g.1.iter().copied()).collect();
            if all.is_empty() {
                continue;
            }
            let (_, yunit_shown) = readable(all, &yunit, false);
            p.y_label = with_unit(&yname, &yunit_shown);
            // a grid connects the runs of a group; scattered samples stay points
            let connect = axis.is_some_and(|i| distinct(i).len() < n_ok);
            for (label, pts) in groups {
                let (pts, _) = readable(pts, &yunit, false);
                let s = Series::new(label, pts);
                p.add(if connect { s.with_markers() } else { s.points_only() });
            }
            out.push((format!("{}_vs_{}.png", sanitize(name), xfile), p));
        }
    }
    out
}

fn sanitize(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' { c } else { '_' }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_is_linear_and_bounded() {
        let rows = vec![vec![0.0, 1.0], vec![10.0, 3.0], vec![20.0, 7.0]];
        assert_eq!(interpolate(&rows, 1, 5.0), Some(2.0));
        assert_eq!(interpolate(&rows, 1, 15.0), Some(5.0));
        assert_eq!(interpolate(&rows, 1, 20.0), Some(7.0));
        assert_eq!(interpolate(&rows, 1, 0.0), Some(1.0));
        assert_eq!(interpolate(&rows, 1, 20.5), None);
    }
}
