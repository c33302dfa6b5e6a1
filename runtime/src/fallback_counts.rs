//! How often the fixed-point kernel (targets without an FPU, `Arithmetic::Fixed`)
//! handed a template call to its `f32` functions, with the `fallback-counts` feature:
//! a diagnostic for a firmware's own evidence (a fallback costs about ten times its
//! fixed-point twin). Off by default; it adds a load, an add and a store per template
//! call.
//!
//! The counters are process-wide statics updated by a load and a store (no
//! read-modify-write instruction, so every target has them): counts from several
//! threads at once may be lost. They wrap at `2^32`.

use core::sync::atomic::{AtomicU32, Ordering};

/// Template calls of the fixed-point kernel since the last reset.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FallbackCounts {
    /// Value function calls (`log_likelihood`, the value passes of `marginals`).
    pub value_calls: u32,
    /// Of those, answered by the `f32` function (the value was below its threshold).
    pub value_fallbacks: u32,
    /// Posterior function calls (value and local posteriors of a component).
    pub posterior_calls: u32,
    /// Of those, answered by the `f32` function.
    pub posterior_fallbacks: u32,
}

static VALUE_CALLS: AtomicU32 = AtomicU32::new(0);
static VALUE_FALLBACKS: AtomicU32 = AtomicU32::new(0);
static POSTERIOR_CALLS: AtomicU32 = AtomicU32::new(0);
static POSTERIOR_FALLBACKS: AtomicU32 = AtomicU32::new(0);

/// The counts since the last [`reset_fallback_counts`] (or the program's start).
pub fn fallback_counts() -> FallbackCounts {
    FallbackCounts {
        value_calls: VALUE_CALLS.load(Ordering::Relaxed),
        value_fallbacks: VALUE_FALLBACKS.load(Ordering::Relaxed),
        posterior_calls: POSTERIOR_CALLS.load(Ordering::Relaxed),
        posterior_fallbacks: POSTERIOR_FALLBACKS.load(Ordering::Relaxed),
    }
}

/// Sets every count to 0.
pub fn reset_fallback_counts() {
    for c in [
        &VALUE_CALLS,
        &VALUE_FALLBACKS,
        &POSTERIOR_CALLS,
        &POSTERIOR_FALLBACKS,
    ] {
        c.store(0, Ordering::Relaxed);
    }
}

fn bump(c: &AtomicU32) {
    c.store(c.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
}

/// Counts one value function call, and its fallback when `fallback`.
pub(crate) fn count_value(fallback: bool) {
    bump(&VALUE_CALLS);
    if fallback {
        bump(&VALUE_FALLBACKS);
    }
}

/// Counts one posterior function call, and its fallback when `fallback`.
pub(crate) fn count_posterior(fallback: bool) {
    bump(&POSTERIOR_CALLS);
    if fallback {
        bump(&POSTERIOR_FALLBACKS);
    }
}
