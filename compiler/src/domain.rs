//! Domains of numeric settings.
//!
//! Every settings type ([`crate::learn::TrainingSettings`],
//! [`crate::mrf::CooccurrenceParams`], [`crate::mrf::BpOptions`], the tree mixture's
//! `TreeTraining`, the experiments' per-model settings) has one `check` that tests each
//! numeric field against the domain its documentation states, with the helpers here.
//! The functions that use a setting call it, and so do the command-line tool (for
//! flags, and for settings and training JSON files) before any work, so a value is
//! accepted or refused the same way whichever path it came by. Errors name the
//! setting by its path in the JSON form (`graphspn.training.temperature`), which the
//! command-line tool maps to its flag.

/// A setting outside its domain.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{setting} = {value}: {domain}")]
pub struct DomainError {
    /// The setting, as its path in the settings' JSON form (e.g. `potentials.coupling`).
    pub setting: String,
    /// The value given.
    pub value: String,
    /// What it must be, e.g. `must be finite and in [0, 1]`.
    pub domain: String,
}

impl DomainError {
    /// The same error for a setting nested under `parent` (`parent.setting`).
    pub fn under(mut self, parent: &str) -> Self {
        self.setting = format!("{parent}.{}", self.setting);
        self
    }
}

/// Which end of an interval is included.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// The bound belongs to the domain (`[`, `]`).
    Closed,
    /// It does not (`(`, `)`).
    Open,
}

/// `value` is finite and within `lo`–`hi` (each end closed or open).
pub fn real(
    setting: &str,
    value: f64,
    (lo, lo_end): (f64, End),
    (hi, hi_end): (f64, End),
) -> Result<(), DomainError> {
    let above = match lo_end {
        End::Closed => value >= lo,
        End::Open => value > lo,
    };
    let below = match hi_end {
        End::Closed => value <= hi,
        End::Open => value < hi,
    };
    if value.is_finite() && above && below {
        return Ok(());
    }
    let open = if lo_end == End::Closed { '[' } else { '(' };
    let close = if hi_end == End::Closed { ']' } else { ')' };
    let domain = if hi == f64::INFINITY {
        match lo_end {
            End::Closed => format!("must be finite and ≥ {lo}"),
            End::Open => format!("must be finite and > {lo}"),
        }
    } else {
        format!("must be finite and in {open}{lo}, {hi}{close}")
    };
    Err(DomainError {
        setting: setting.into(),
        value: value.to_string(),
        domain,
    })
}

/// `value` is finite and in `[lo, hi]`.
pub fn closed(setting: &str, value: f64, lo: f64, hi: f64) -> Result<(), DomainError> {
    real(setting, value, (lo, End::Closed), (hi, End::Closed))
}

/// `value` is finite and in `(lo, hi]`.
pub fn left_open(setting: &str, value: f64, lo: f64, hi: f64) -> Result<(), DomainError> {
    real(setting, value, (lo, End::Open), (hi, End::Closed))
}

/// `value` is a count from `lo` to `hi` (inclusive).
pub fn count(setting: &str, value: u64, lo: u64, hi: u64) -> Result<(), DomainError> {
    if (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(DomainError {
        setting: setting.into(),
        value: value.to_string(),
        domain: format!("must be from {lo} to {hi}"),
    })
}

/// Largest number of evidence rounds per map and noise level of an experiment
/// (`rounds`, `--rounds`).
pub const MAX_ROUNDS: usize = 1000;

/// Decompositions an instance GraphSPN mixes (`count`, `--decompositions`, `--count`):
/// 1 to [`crate::decompose::MAX_DECOMPOSITIONS`].
pub fn decompositions(setting: &str, value: usize) -> Result<(), DomainError> {
    count(
        setting,
        value as u64,
        1,
        crate::decompose::MAX_DECOMPOSITIONS as u64,
    )
}

/// Spanning trees of a tree mixture (`trees`, `--trees`, `compile --count`): 1 to
/// [`crate::treemix::MAX_TREES`].
pub fn trees(setting: &str, value: usize) -> Result<(), DomainError> {
    count(setting, value as u64, 1, crate::treemix::MAX_TREES as u64)
}

/// Evidence rounds per map and noise level (`rounds`, `--rounds`): 1 to
/// [`MAX_ROUNDS`].
pub fn rounds(setting: &str, value: usize) -> Result<(), DomainError> {
    count(setting, value as u64, 1, MAX_ROUNDS as u64)
}

/// Maps per building (`maps_per_building`, `--maps`, `--max-maps`): at least 1.
pub fn maps(setting: &str, value: usize) -> Result<(), DomainError> {
    count(setting, value as u64, 1, u64::MAX)
}

/// Places of a synthetic office floor (`graphspn generate --places`, `--synthetic`):
/// 10 to 100,000.
pub fn synthetic_places(setting: &str, value: usize) -> Result<(), DomainError> {
    count(setting, value as u64, 10, 100_000)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn domains_name_the_setting_the_value_and_the_interval() {
        let e = closed("prior_correction", -0.5, 0.0, 1.0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "prior_correction = -0.5: must be finite and in [0, 1]"
        );
        assert_eq!(
            e.under("graphspn").setting,
            "graphspn.prior_correction".to_string()
        );
        let e = left_open("tolerance", 0.0, 0.0, 1.0).unwrap_err();
        assert!(e.domain.contains("(0, 1]"), "{e}");
        let e = real("x", -1.0, (0.0, End::Closed), (f64::INFINITY, End::Open)).unwrap_err();
        assert!(e.domain.contains("≥ 0"), "{e}");
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(closed("x", v, f64::MIN, f64::MAX).is_err());
        }
        assert!(closed("x", 1.0, 0.0, 1.0).is_ok());
        assert!(left_open("x", 1.0, 0.0, 1.0).is_ok());
        assert!(count("n", 0, 1, 10).is_err() && count("n", 11, 1, 10).is_err());
        assert!(decompositions("count", 1000).is_ok() && decompositions("count", 1001).is_err());
        assert!(trees("trees", 64).is_ok() && trees("trees", 0).is_err());
        assert!(rounds("rounds", 0).is_err() && maps("maps", 0).is_err());
    }

    /// The shipped configurations (the full and quick runs, their validation grids and
    /// the tiny grid) are within every domain: the checks refuse nothing they use.
    #[cfg(feature = "host")]
    #[test]
    fn the_shipped_configurations_are_within_their_domains() {
        use crate::experiments::config::{ReproduceConfig, check_settings};
        use crate::experiments::grid::ValidationGrid;
        for cfg in [ReproduceConfig::full(0), ReproduceConfig::quick(0)] {
            check_settings(&cfg).unwrap();
        }
        ValidationGrid::tiny().check().unwrap();
    }
}
