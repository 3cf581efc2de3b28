//! Every range table of the run kinds and the physics below them, for `sinterdem keys`
//! (docs/case-file.md), `sinterdem check` and the calibration's parameter bounds. Each module
//! owns its table and checks against it; this is only the list (calibration files add
//! `crate::calibrate::RANGES`, which sits above the kinds).

use crate::config::ranges::{self, Range};

/// The range tables of the shared keys, the models and the kinds, in the order of
/// docs/case-file.md: the explicit sintering laws' tables come from their registration
/// (`explicit_sinter::laws::LAWS`), so a new law is listed without a line here.
pub fn tables() -> Vec<&'static [Range]> {
    let mut t: Vec<&'static [Range]> = vec![ranges::TABLE, crate::models::diffusion7::RANGES, super::generate::RANGES];
    t.extend(super::explicit_sinter::laws::LAWS.iter().map(|law| law.ranges));
    t.push(super::explicit_sinter::RANGES);
    t.push(crate::coupled::cell::RANGES);
    t.push(super::rve::RANGES);
    t
}

/// Looks `key` up in every table of [`tables`].
pub fn lookup(key: &str) -> Option<&'static Range> {
    ranges::lookup_in(&tables(), key)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn keys_are_unique_across_tables() {
        let all: Vec<&Range> = tables().iter().flat_map(|t| t.iter()).collect();
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a.key, b.key);
            }
        }
        assert_eq!(lookup("luding.k1").map(|r| r.key), Some("luding.k1"));
        assert_eq!(lookup("materials.copper.density").map(|r| r.unit), Some("kg/m^3"));
    }
}
