//! ROC/AUC and tie-aware accuracy used by the reproduction.

use graphspn_compiler::experiments::novelty::{auc, roc_curve};
use graphspn_compiler::experiments::protocol::accuracy;
use proptest::prelude::*;

#[test]
fn auc_extremes_and_ties() {
    // Low score = novel.
    let separated = [(0.1, true), (0.2, true), (0.8, false), (0.9, false)];
    assert_eq!(auc(&separated), 1.0);
    let reversed = [(0.1, false), (0.2, false), (0.8, true), (0.9, true)];
    assert_eq!(auc(&reversed), 0.0);
    let tied = [(0.5, true), (0.5, false), (0.5, true), (0.5, false)];
    assert_eq!(auc(&tied), 0.5);
    let c = roc_curve(&separated);
    assert_eq!(c.first(), Some(&(0.0, 0.0)));
    assert_eq!(c.last(), Some(&(1.0, 1.0)));
}

#[test]
fn accuracy_splits_ties() {
    let probs = vec![vec![0.5, 0.5], vec![0.9, 0.1], vec![0.2, 0.8]];
    // Place 0 ties (½), place 1 right, place 2 wrong.
    assert_eq!(accuracy(&probs, &[0, 0, 0], &[0, 1, 2]), 0.5);
    assert_eq!(accuracy(&probs, &[1, 0, 1], &[1, 2]), 1.0);
    assert!(accuracy(&probs, &[0, 0, 0], &[]).is_nan());
}

proptest! {
    /// AUC equals the Mann–Whitney statistic P(novel < non-novel) + ½ P(tie).
    #[test]
    fn auc_is_mann_whitney(pts in proptest::collection::vec((0u8..6, any::<bool>()), 2..30)) {
        let pts: Vec<(f64, bool)> = pts.into_iter().map(|(s, n)| (s as f64, n)).collect();
        let pos: Vec<f64> = pts.iter().filter(|p| p.1).map(|p| p.0).collect();
        let neg: Vec<f64> = pts.iter().filter(|p| !p.1).map(|p| p.0).collect();
        prop_assume!(!pos.is_empty() && !neg.is_empty());
        let mut w = 0.0;
        for &a in &pos {
            for &b in &neg {
                w += if a < b { 1.0 } else if a == b { 0.5 } else { 0.0 };
            }
        }
        let mw = w / (pos.len() * neg.len()) as f64;
        prop_assert!((auc(&pts) - mw).abs() < 1e-12);
    }
}
