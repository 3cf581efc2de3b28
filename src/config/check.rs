//! `sinterdem check` as a library call: parse, range-check, plausibility and scene construction
//! of a case of any kind, without running it (the fuzz test drives this path).

use crate::error::{ConfigError, Error};
use std::path::Path;

/// Checks a loaded case (`load_case` output; overrides applied). `base` is the case file's
/// directory. Returns the one-line description `sinterdem check` prints after the file name.
pub fn check_case(value: toml::Value, base: &Path) -> Result<String, Error> {
    let kind = value.get("kind").and_then(|k| k.as_str()).unwrap_or("heat").to_string();
    Ok(match kind.as_str() {
        "heat" => {
            let prep = crate::heat::run::prepare(value, base)?;
            format!("ok (heat case, {} particles, {} contacts)", prep.scene.particles.len(), prep.pipes.pairs.len())
        }
        "compact" => {
            let sim = crate::scheduler::prepare(value, base, &mut |_| {})?;
            format!("ok (compact case, {} particles, {} contacts)", sim.prep.scene.particles.len(), sim.contacts.len())
        }
        "generate" => {
            crate::packing::check_generate_case(&value)?;
            "ok (packing generation case)".into()
        }
        "pair" => {
            crate::models::diffusion7::pair::check_pair_case(&value)?;
            "ok (pair case)".into()
        }
        "explicit_sinter" => {
            crate::explicit::protocol::check_explicit_case(&value)?;
            "ok (explicit_sinter case)".into()
        }
        k => return Err(ConfigError::invalid(format!("kind = \"{k}\": expected heat, compact, pair, generate or explicit_sinter")).into()),
    })
}

/// [`check_case`] of a case file with `--set` overrides.
pub fn check_file(path: &Path, overrides: &[String]) -> Result<String, Error> {
    let value = super::load_case(path, overrides)?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_else(|| ".".into());
    check_case(value, &base)
}
