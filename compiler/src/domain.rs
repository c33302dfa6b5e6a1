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
