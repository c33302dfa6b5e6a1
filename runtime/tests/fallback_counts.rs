//! The `fallback-counts` feature (enabled for the runtime's own tests by its
//! dev-dependency on itself): the fixed-point fixture counts one value call per
//! component for `log_likelihood` and one posterior call per component for
//! `marginals`, a fallback exactly where the fixed-point value is below its
//! threshold, and a reset clears every count.
#![cfg(feature = "fallback-counts")]

use graphspn_runtime::{CompiledMap, FallbackCounts, fallback_counts, reset_fallback_counts};

#[allow(missing_docs, clippy::all)]
mod spn_dense_fixed {
    include!("fixtures/spn_dense_fixed.rs");
}
use spn_dense_fixed::{Map, NUM_CLASSES, NUM_COMPONENTS, NUM_PLACES};

type Rows = [[f32; NUM_CLASSES]; NUM_PLACES];

/// The counts of `log_likelihood` and of `marginals` on `e`, each from a reset.
fn counts(e: &Rows) -> (FallbackCounts, FallbackCounts) {
    reset_fallback_counts();
    Map::log_likelihood(e).unwrap();
    let ll = fallback_counts();
    reset_fallback_counts();
    Map::marginals(e, &mut [[0.0; NUM_CLASSES]; NUM_PLACES]).unwrap();
    (ll, fallback_counts())
}

#[test]
fn calls_and_fallbacks_are_counted_and_reset() {
    let k = NUM_COMPONENTS as u32;
    // All ones: every template value is 1, far above its threshold.
    let (ll, marg) = counts(&[[1.0; NUM_CLASSES]; NUM_PLACES]);
    assert_eq!(
        ll,
        FallbackCounts {
            value_calls: k,
            ..Default::default()
        }
    );
    assert_eq!(marg.posterior_calls, k, "{marg:?}");
    assert_eq!((marg.value_fallbacks, marg.posterior_fallbacks), (0, 0));
    // The fixture's templates never fall back (2 classes: every value is above its
    // threshold); the wrappers count a fixed-point value below `min` as a fallback.
    use graphspn_runtime::__private::{Fx, fx_fwd, fx_post};
    let x = [[1.0f32; 2]; 1];
    reset_fallback_counts();
    // `f32` answers 0.5, which no fixed-point value here converts to.
    for (fx, fell_back) in [(9, true), (10, false), (u32::MAX, false)] {
        let v = fx_fwd(&x, 10, |_| Fx(fx), |_| 0.5);
        assert_eq!(v == 0.5, fell_back, "value {fx}");
        let p = fx_post(&x, &mut [[0.0; 2]; 1], 10, |_, _| Fx(fx), |_, _| 0.5);
        assert_eq!(p == 0.5, fell_back, "posterior {fx}");
    }
    let want = FallbackCounts {
        value_calls: 3,
        value_fallbacks: 1,
        posterior_calls: 3,
        posterior_fallbacks: 1,
    };
    assert_eq!(fallback_counts(), want);
    reset_fallback_counts();
    assert_eq!(fallback_counts(), FallbackCounts::default());
}
