//! Bad queries: one test per invalid-evidence error and per invalid `fixed`, plus
//! zero likelihood and exact-zero evidence handling on a hand-built SPN.

use graphspn_compiler::interpreter::{
    Evaluator, Evidence, InferenceError, log_likelihood, marginals, mpe,
};
use graphspn_compiler::runtime::EvidenceError;
use graphspn_compiler::spn::{Node, Spn, SpnBuilder, SpnError};

/// Y0 ∈ {0,1,2}, Y1 ∈ {0,1}: 0.4·[Y0=0]·[Y1=1] + 0.6·P(Y0)·P(Y1) with
/// P(Y0) = (0.5, 0.5, 0) and P(Y1) = (0.25, 0.75).
fn spn() -> Spn {
    let mut b = SpnBuilder::new(vec![3, 2]);
    let a: Vec<u32> = (0..3).map(|c| b.add_leaf(0, c)).collect();
    let c: Vec<u32> = (0..2).map(|k| b.add_leaf(1, k)).collect();
    let p1 = b.add_product(vec![a[0], c[1]]);
    let s0 = b.add_sum(a.clone(), vec![0.5, 0.5, 0.0]);
    let s1 = b.add_sum(c.clone(), vec![0.25, 0.75]);
    let p2 = b.add_product(vec![s0, s1]);
    let root = b.add_sum(vec![p1, p2], vec![0.4, 0.6]);
    b.finish(root).unwrap()
}

fn ev_err(rows: Vec<Vec<f64>>) -> (InferenceError, String) {
    let e = log_likelihood(&spn(), &[None, None], &Evidence::from_rows(rows)).unwrap_err();
    let m = e.to_string();
    (e, m)
}

#[test]
fn not_finite() {
    for bad in [f64::NAN, f64::INFINITY] {
        let (e, m) = ev_err(vec![vec![1.0, 1.0, 1.0], vec![bad, 1.0]]);
        assert_eq!(
            e,
            InferenceError::Evidence(EvidenceError::NotFinite {
                place: 1,
                place_id: 1,
                class: 0
            })
        );
        assert!(m.contains("place 1") && m.contains("class 0"), "{m}");
    }
}

#[test]
fn negative() {
    let (e, m) = ev_err(vec![vec![1.0, -0.5, 1.0], vec![1.0, 1.0]]);
    assert_eq!(
        e,
        InferenceError::Evidence(EvidenceError::Negative {
            place: 0,
            place_id: 0,
            class: 1
        })
    );
    assert!(m.contains("place 0") && m.contains("class 1"), "{m}");
}

#[test]
fn no_mass() {
    let (e, m) = ev_err(vec![vec![1.0, 1.0, 1.0], vec![0.0, 0.0]]);
    assert_eq!(
        e,
        InferenceError::Evidence(EvidenceError::NoMass {
            place: 1,
            place_id: 1
        })
    );
    assert!(m.contains("place 1"), "{m}");
}

#[test]
fn wrong_shape() {
    let (e, m) = ev_err(vec![vec![1.0, 1.0, 1.0]]);
    assert_eq!(
        e,
        InferenceError::Evidence(EvidenceError::WrongLength {
            expected: 2,
            found: 1
        })
    );
    assert!(
        m.contains("a slice of 1 entries where the map has 2 places"),
        "{m}"
    );
    let (e, m) = ev_err(vec![vec![1.0, 1.0, 1.0], vec![1.0, 1.0, 1.0]]);
    assert_eq!(
        e,
        InferenceError::Evidence(EvidenceError::WrongShape {
            place: 1,
            expected: 2,
            found: 3
        })
    );
    assert!(m.contains("place index 1"), "{m}");
}

#[test]
fn bad_fixed() {
    let s = spn();
    let u = Evidence::uniform(&s);
    let e = marginals(&s, &[None], &u).unwrap_err();
    assert_eq!(
        e,
        InferenceError::FixedWrongLength {
            expected: 2,
            found: 1
        }
    );
    let e = mpe(&s, &[None, Some(2)], &u).unwrap_err();
    assert_eq!(
        e,
        InferenceError::FixedClassOutOfRange {
            var: 1,
            class: 2,
            classes: 2
        }
    );
    assert!(e.to_string().contains("variable 1"), "{e}");
}

#[test]
fn invalid_spn() {
    let mut s = spn();
    s.root = 99;
    let e = log_likelihood(&s, &[None, None], &Evidence::uniform(&s)).unwrap_err();
    assert!(matches!(
        e,
        InferenceError::InvalidSpn(SpnError::RootOutOfRange { root: 99, .. })
    ));
    assert!(e.to_string().contains("root node 99"));
}

#[test]
fn zero_likelihood_is_an_error_not_nan() {
    // Y0 = 2 has probability 0 under the model.
    let s = spn();
    let rows = vec![vec![0.0, 0.0, 1.0], vec![1.0, 1.0]];
    let mut ev = Evaluator::new(&s).unwrap();
    let zero = InferenceError::Evidence(EvidenceError::ZeroLikelihood);
    let e = Evidence::from_rows(rows);
    assert_eq!(ev.log_likelihood(&[None, None], &e), Err(zero.clone()));
    assert_eq!(ev.marginals(&[None, None], &e).unwrap_err(), zero);
    assert_eq!(ev.mpe(&[None, None], &e).unwrap_err(), zero);
    let u = Evidence::uniform(&s);
    assert_eq!(ev.marginals(&[Some(2), None], &u).unwrap_err(), zero);
    assert!(zero.to_string().contains("probability zero"));
}

#[test]
fn exact_zero_evidence_and_fixed() {
    // By hand: P(y0, y1) = 0.4·[y0=0][y1=1] + 0.6·p0(y0)·p1(y1).
    let p0 = [0.5, 0.5, 0.0];
    let p1 = [0.25, 0.75];
    let joint =
        |a: usize, c: usize| 0.4 * f64::from(u8::from(a == 0 && c == 1)) + 0.6 * p0[a] * p1[c];
    let alpha = [vec![0.0, 2.0, 1.0], vec![0.5, 0.0]];
    // Evidence excludes Y0 = 0 and Y1 = 1: only (1, 0) is left.
    let s = spn();
    let m = marginals(&s, &[None, None], &Evidence::from_rows(alpha.to_vec())).unwrap();
    let expected = (joint(1, 0) * 2.0 * 0.5).ln();
    assert!((m.log_likelihood - expected).abs() < 1e-12);
    assert_eq!(m.probs, vec![vec![0.0, 1.0, 0.0], vec![1.0, 0.0]]);
    // Uniform evidence, Y1 fixed to 1.
    let m = marginals(&s, &[None, Some(1)], &Evidence::uniform(&s)).unwrap();
    let l: f64 = (0..3).map(|a| joint(a, 1)).sum();
    assert!((m.log_likelihood - l.ln()).abs() < 1e-12);
    for a in 0..3 {
        assert!(
            (m.probs[0][a] - joint(a, 1) / l).abs() < 1e-12,
            "{:?}",
            m.probs
        );
    }
    assert_eq!(m.probs[1], vec![0.0, 1.0]);
    // MPE: best joint is (0,1) = 0.4 + 0.6·0.5·0.75 = 0.625; the best induced tree is
    // the 0.4 branch.
    let r = mpe(&s, &[None, None], &Evidence::uniform(&s)).unwrap();
    assert_eq!(r.assignment, vec![0, 1]);
    assert!((r.log_max_product - 0.4f64.ln()).abs() < 1e-12);
    assert!((r.log_probability - joint(0, 1).ln()).abs() < 1e-12);
}

#[test]
fn uniform_evidence_has_likelihood_one() {
    let s = spn();
    let ll = log_likelihood(&s, &[None, None], &Evidence::uniform(&s)).unwrap();
    assert!(ll.abs() < 1e-12, "{ll}");
    assert!(matches!(s.nodes[0], Node::Leaf { var: 0, class: 0 }));
}
