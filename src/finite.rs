//! Finiteness guards of stage outputs (issue 16): a NaN or inf that leaves a stage becomes a
//! [`ModelError`] naming the stage, the step and the particle or contact, instead of travelling
//! silently into the series and the summary. One linear scan per stage and step: negligible beside
//! the stage itself.

use crate::error::{ModelError, fmt_value};

/// The first entry of `values` that is not finite: (index, value).
pub fn first_non_finite<I: IntoIterator<Item = f64>>(values: I) -> Option<(usize, f64)> {
    values.into_iter().enumerate().find(|(_, v)| !v.is_finite())
}

/// Fails with a [`ModelError`] if an entry is not finite. `stage` names the stage (e.g.
/// "heat"), `item` what an index counts ("particle", "contact"), `quantity` the value.
pub fn ensure_finite<I: IntoIterator<Item = f64>>(stage: &str, step: u64, t: f64, item: &str, quantity: &str, values: I) -> Result<(), ModelError> {
    match first_non_finite(values) {
        None => Ok(()),
        Some((i, v)) => Err(ModelError::new(format!("{stage} stage produced a non-finite {quantity} ({}) at {item} {i}", fmt_value(v)))
            .with_context(format!("step {step}, t = {} s", fmt_value(t)))),
    }
}

/// [`ensure_finite`] over fixed-size groups (a contact's 7-DOF state, a particle's 3 components):
/// the index reported is the group's.
pub fn ensure_finite_groups<'a, const N: usize, I: IntoIterator<Item = &'a [f64; N]>>(
    stage: &str,
    step: u64,
    t: f64,
    item: &str,
    quantity: &str,
    groups: I,
) -> Result<(), ModelError> {
    for (i, g) in groups.into_iter().enumerate() {
        if let Some(&v) = g.iter().find(|v| !v.is_finite()) {
            return Err(ModelError::new(format!("{stage} stage produced a non-finite {quantity} ({}) at {item} {i}", fmt_value(v)))
                .with_context(format!("step {step}, t = {} s", fmt_value(t))));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn names_stage_step_and_item() {
        assert!(ensure_finite("heat", 3, 1.0, "particle", "temperature", [1.0, 2.0]).is_ok());
        let e = ensure_finite("heat", 3, 1.0, "particle", "temperature", [1.0, f64::NAN]).unwrap_err().to_string();
        assert!(e.contains("heat stage") && e.contains("particle 1") && e.contains("step 3") && e.contains("temperature"), "{e}");
        let e = ensure_finite_groups("diffusion", 7, 2.0, "contact", "7-DOF state", [&[1.0; 7], &[1.0, f64::INFINITY, 0.0, 0.0, 0.0, 0.0, 0.0]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("contact 1") && e.contains("step 7") && e.contains("inf"), "{e}");
    }
}
