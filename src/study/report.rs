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
    if plots {
        write_plots(study, dir, rows)?;
    }
    Ok(c)
}

/// A PNG per numeric output against each numeric parameter (against the run index when the study
/// has none, e.g. a `cases` study).
fn write_plots(study: &Study, dir: &Path, rows: &[Row]) -> Result<(), Error> {
    let pdir = dir.join("plots");
    crate::io::ensure_dir(&pdir)?;
    let ok: Vec<&Row> = rows.iter().filter(|r| r.record.as_ref().is_some_and(RunRecord::ok)).collect();
    let Some(first) = ok.first() else { return Ok(()) };
    let numeric = |s: &str| s.parse::<f64>().ok().filter(|x| x.is_finite());
    let mut axes: Vec<(String, bool, Box<dyn Fn(&Row) -> Option<f64>>)> = Vec::new();
    for (i, p) in study.parameters.iter().enumerate() {
        if ok.iter().all(|r| numeric(&r.run.parameters[i].1).is_some()) {
            let log = matches!(p.values, Values::Range { log: true, .. } | Values::Bounds { log: true, .. });
            axes.push((p.name.clone(), log, Box::new(move |r: &Row| numeric(&r.run.parameters[i].1))));
        }
    }
    if axes.is_empty() {
        axes.push(("run".into(), false, Box::new(|r: &Row| Some(r.run.index as f64))));
    }
    for (k, (name, _)) in first.outputs.iter().enumerate() {
        let pts_of = |f: &dyn Fn(&Row) -> Option<f64>| -> Vec<(f64, f64)> { ok.iter().filter_map(|r| Some((f(r)?, numeric(&r.outputs[k].1)?))).collect() };
        for (pname, log, f) in &axes {
            let pts = pts_of(f.as_ref());
            if pts.is_empty() {
                continue;
            }
            let mut p = Plot::new(format!("{}: {name} against {pname}", study.title)).labels(pname.clone(), name.clone()).log_x(*log);
            p.add(Series::new(format!("{} runs", pts.len()), pts).points_only());
            let file = format!("{}_vs_{}.png", sanitize(name), sanitize(pname));
            p.save_png(&pdir.join(file))?;
        }
    }
    Ok(())
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
