//! Real generated modules (`fixtures/*.rs`, written by the compiler's `runtime_fixtures`
//! test: GraphSPN and tree mixture, `f32` and `f64`, scalar and SIMD, float and fixed
//! point) run through every entry point of [`CompiledMap`] and compared with what the
//! brute-force oracle or `TreeInstance` answered (`fixtures/*.expected`). The runtime
//! drives all of their arithmetic outside the templates' own functions, so this is the
//! runtime's end-to-end test, and it needs no generator: a change to the runtime is
//! checked in seconds.
//!
//! Each `.expected` file holds 9 evidence cases (random, random, exact zeros, tiny
//! values, uniform, all ones, case 6 = the product of cases 0 and 1, case 7 = case 0
//! scaled by `2^-135` in `f32` or `2^-1035` in `f64`: every entry subnormal, and case 8
//! = sharp rows, `1e-30` off one class), each with its
//! labels and the reference's log-likelihood, labelled log-likelihood, MPE value and
//! marginals (`zero`: the evidence has zero likelihood).

use graphspn_runtime::{CompiledMap, EvidenceError};

macro_rules! fixtures {
    ($($name:ident),* $(,)?) => {
        $(
            #[allow(missing_docs, clippy::all)]
            mod $name {
                include!(concat!("fixtures/", stringify!($name), ".rs"));
            }
        )*
        /// Every fixture: name, checker and expected answers.
        const FIXTURES: &[(&str, fn(&str, &str), &str)] = &[
            $((
                stringify!($name),
                check::<$name::Map>,
                include_str!(concat!("fixtures/", stringify!($name), ".expected")),
            ),)*
        ];
    };
}

fixtures!(
    spn_tiny_simd_f32,
    spn_ten_simd_f32,
    spn_ten_simd_f64,
    spn_grid_simd_f32_two_pass,
    spn_dense_simd_f32,
    spn_dense_simd_f64,
    spn_dense_scalar_f32,
    spn_dense_fixed,
    spn_dense_four_fixed,
    spn_floored_star_fixed,
    spn_sparse_scalar_f32,
    spn_layered_scalar_f64,
    spn_layered_simd_f32,
    trees_scalar_f32,
    trees_simd_f32,
    trees_scalar_f64,
    trees_simd_f64,
    trees_fixed,
    trees_fixed_float_messages,
    trees_hub_scalar_f32,
    trees_two_hubs_simd_f32,
    trees_two_hubs_scalar_f32,
    trees_sharp_hubs_simd_f32,
    trees_sharp_hubs_scalar_f32,
);

/// The scalar types of generated modules.
trait Num: Copy + PartialOrd + core::fmt::Debug {
    fn from_f64(v: f64) -> Self;
    fn to_f64(self) -> f64;
    /// Tolerance of log values (relative, at least absolute) and marginals (absolute):
    /// about 60 (`f32`) and 2,000 (`f64`) times the largest error the fixtures show, so
    /// that a change of one rounding's size still passes and a wrong term fails.
    const TOL: f64;
}

impl Num for f32 {
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    const TOL: f64 = 1e-5;
}

impl Num for f64 {
    fn from_f64(v: f64) -> Self {
        v
    }
    fn to_f64(self) -> f64 {
        self
    }
    const TOL: f64 = 1e-12;
}

/// One evidence case of an `.expected` file.
struct Case {
    evidence: Vec<f64>,
    labels: Vec<u16>,
    ll: Option<f64>,
    labelled: Option<f64>,
    mpe: Option<f64>,
    marginals: Vec<f64>,
}

fn parse(text: &str) -> (usize, usize, Vec<Case>) {
    let mut lines = text.lines();
    let head: Vec<usize> = lines
        .next()
        .unwrap()
        .split_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect();
    let values = |line: Option<&str>, key: &str| -> Vec<String> {
        let line = line.unwrap_or_else(|| panic!("missing {key}"));
        let mut t = line.split_whitespace();
        assert_eq!(t.next(), Some(key), "{line}");
        t.map(str::to_string).collect()
    };
    let number = |v: &[String]| match v[0].as_str() {
        "zero" => None,
        s => Some(s.parse().unwrap()),
    };
    let mut cases = vec![];
    while let Some(line) = lines.next() {
        assert!(line.starts_with("case "), "{line}");
        let floats = |v: Vec<String>| v.iter().map(|s| s.parse().unwrap()).collect();
        cases.push(Case {
            evidence: floats(values(lines.next(), "evidence")),
            labels: values(lines.next(), "labels")
                .iter()
                .map(|s| s.parse().unwrap())
                .collect(),
            ll: number(&values(lines.next(), "log_likelihood")),
            labelled: number(&values(lines.next(), "labelled")),
            mpe: number(&values(lines.next(), "mpe")),
            marginals: floats(values(lines.next(), "marginals")),
        });
    }
    (head[0], head[1], cases)
}

/// `|a − b| ≤ tol · max(|a|, |b|, 1)`.
fn close(a: f64, b: f64, tol: f64) -> bool {
    a == b || (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

struct Checker<'a> {
    name: &'a str,
    tol: f64,
}

impl Checker<'_> {
    /// A log value against the reference's (`None`: the call must report zero likelihood).
    fn log<S: Num>(&self, what: &str, got: Result<S, EvidenceError>, want: Option<f64>) {
        match (got, want) {
            (Ok(g), Some(w)) => assert!(
                close(g.to_f64(), w, self.tol),
                "{}: {what} {g:?}, expected {w}",
                self.name
            ),
            (Err(EvidenceError::ZeroLikelihood), None) => {}
            (g, w) => panic!("{}: {what} {g:?}, expected {w:?}", self.name),
        }
    }

    fn rows<M: CompiledMap>(&self, what: &str, got: &[M::Row], want: &[f64])
    where
        M::Scalar: Num,
    {
        let got: Vec<f64> = got
            .iter()
            .flat_map(|r| r.as_ref().iter().map(|v| v.to_f64()))
            .collect();
        assert_eq!(got.len(), want.len(), "{}: {what}", self.name);
        for (i, (g, w)) in got.iter().zip(want).enumerate() {
            assert!(
                (g - w).abs() <= self.tol,
                "{}: {what} entry {i}: {g} vs {w}",
                self.name
            );
        }
    }
}

fn rows<M: CompiledMap>(flat: &[f64]) -> Vec<M::Row>
where
    M::Scalar: Num,
{
    let c = M::NUM_CLASSES;
    flat.chunks(c)
        .map(|ch| {
            let mut r = M::ZERO_ROW;
            for (o, &v) in r.as_mut().iter_mut().zip(ch) {
                *o = M::Scalar::from_f64(v);
            }
            r
        })
        .collect()
}

/// Every entry point of `M` on every case of `expected`.
fn check<M: CompiledMap>(name: &str, expected: &str)
where
    M::Scalar: Num,
{
    let (n, c, cases) = parse(expected);
    assert_eq!((n, c), (M::NUM_PLACES, M::NUM_CLASSES), "{name}");
    // Fixed-point modules too: their documented bounds (`2^-13` per value, `2^-10` per
    // local posterior) are far above what these small maps show (below `2e-7`).
    let tol = M::Scalar::TOL;
    let ck = Checker { name, tol };
    for (k, case) in cases.iter().enumerate() {
        let name = format!("{name} case {k}");
        let ck = Checker { name: &name, tol };
        let e = rows::<M>(&case.evidence);
        ck.log("log_likelihood", M::log_likelihood(&e), case.ll);
        ck.log(
            "labelled_log_likelihood",
            M::labelled_log_likelihood(&case.labels, &e),
            case.labelled,
        );
        // A label past the last class is refused, naming its place.
        let mut bad = case.labels.clone();
        bad[n - 1] = c as u16;
        let refused = Err(EvidenceError::LabelOutOfRange {
            place: n - 1,
            label: c as u16,
            classes: c,
        });
        assert_eq!(M::labelled_log_likelihood(&bad, &e), refused, "{name}");
        let mut labels = vec![0u16; n];
        ck.log("mpe", M::mpe(&e, &mut labels), case.mpe);
        if case.mpe.is_some() {
            // The labelling attains the MPE value: evidence masked to it keeps it.
            let masked: Vec<f64> = case
                .evidence
                .chunks(c)
                .zip(&labels)
                .flat_map(|(r, &l)| {
                    r.iter()
                        .enumerate()
                        .map(move |(j, &v)| if j == usize::from(l) { v } else { 0.0 })
                })
                .collect();
            let mut again = vec![0u16; n];
            ck.log(
                "mpe of its labelling",
                M::mpe(&rows::<M>(&masked), &mut again),
                case.mpe,
            );
            assert_eq!(labels, again, "{name}: mpe labels");
        }
        let mut out = vec![M::ZERO_ROW; n];
        let ll = M::marginals(&e, &mut out);
        ck.log("marginals' log-likelihood", ll, case.ll);
        if case.ll.is_some() {
            ck.rows::<M>("marginals", &out, &case.marginals);
        }
        check_state::<M>(&ck, &e, case);
    }
    check_streaming::<M>(&ck, &cases);
    check_bad_rows::<M>(&ck, &cases[0]);
}

/// A bad row at the last place (a negative entry, a NaN, no mass) is refused by every
/// stateless entry point and by `set_all`, naming that place and its id; the state
/// keeps its evidence.
fn check_bad_rows<M: CompiledMap>(ck: &Checker, case: &Case)
where
    M::Scalar: Num,
{
    let (n, name) = (M::NUM_PLACES, ck.name);
    let (place, place_id) = (n - 1, u64::from(M::PLACE_IDS[n - 1]));
    let good = rows::<M>(&case.evidence);
    let mut s = M::NEW_STATE;
    M::set_all(&mut s, &good).unwrap();
    let before = M::state_log_likelihood(&mut s).unwrap().to_f64();
    let bads: [(f64, EvidenceError); 3] = [
        (
            -1.0,
            EvidenceError::Negative {
                place,
                place_id,
                class: 0,
            },
        ),
        (
            f64::NAN,
            EvidenceError::NotFinite {
                place,
                place_id,
                class: 0,
            },
        ),
        (0.0, EvidenceError::NoMass { place, place_id }),
    ];
    for (v, err) in bads {
        let mut e = good.clone();
        let row = e[place].as_mut();
        row.fill(M::Scalar::from_f64(0.0));
        row[0] = M::Scalar::from_f64(v);
        let refused = Err(err);
        assert_eq!(M::log_likelihood(&e), refused, "{name}: log_likelihood");
        let mut out = vec![M::ZERO_ROW; n];
        assert_eq!(M::marginals(&e, &mut out), refused, "{name}: marginals");
        let mut labels = vec![0u16; n];
        assert_eq!(M::mpe(&e, &mut labels), refused, "{name}: mpe");
        assert_eq!(
            M::labelled_log_likelihood(&case.labels, &e),
            refused,
            "{name}: labelled_log_likelihood"
        );
        assert_eq!(M::set_all(&mut s, &e), Err(err), "{name}: set_all");
        let after = M::state_log_likelihood(&mut s).unwrap().to_f64();
        assert_eq!(before, after, "{name}: set_all refused, evidence kept");
    }
}

/// A state given the case's evidence by `set_all`, by `set_evidence` row by row, and
/// by `observe` of each row on a fresh state (fused onto rows of ones: the row the
/// inference reads is rescaled: a tree mixture's must keep every normal entry, and a
/// GraphSPN's labelled log-likelihood must count a label its row flushed below `2^-24`
/// with its exact value) answers like the stateless entry points.
fn check_state<M: CompiledMap>(ck: &Checker, e: &[M::Row], case: &Case)
where
    M::Scalar: Num,
{
    let n = M::NUM_PLACES;
    let mut s = M::NEW_STATE;
    M::set_all(&mut s, e).unwrap();
    state_answers::<M>(ck, "set_all", &mut s, case);
    let mut s = M::NEW_STATE;
    for (p, r) in e.iter().enumerate() {
        M::set_evidence(&mut s, p, r).unwrap();
    }
    state_answers::<M>(ck, "set_evidence", &mut s, case);
    ck.rows::<M>("state_evidence", M::state_evidence(&s), &case.evidence);
    let mut fused = M::NEW_STATE;
    for (p, r) in e.iter().enumerate() {
        M::observe(&mut fused, p, r).unwrap();
    }
    state_answers::<M>(ck, "observe on a fresh state", &mut fused, case);
    let mut row = M::ZERO_ROW;
    assert!(
        M::state_marginal(&mut s, n, &mut row).is_err(),
        "{}",
        ck.name
    );
}

fn state_answers<M: CompiledMap>(ck: &Checker, how: &str, s: &mut M::State, case: &Case)
where
    M::Scalar: Num,
{
    let n = M::NUM_PLACES;
    ck.log(
        &format!("{how}: log_likelihood"),
        M::state_log_likelihood(s),
        case.ll,
    );
    ck.log(
        &format!("{how}: labelled"),
        M::state_labelled_log_likelihood(s, &case.labels),
        case.labelled,
    );
    let mut bad = case.labels.clone();
    bad[0] = M::NUM_CLASSES as u16;
    assert!(
        M::state_labelled_log_likelihood(s, &bad).is_err(),
        "{}: {how}: a label past the last class",
        ck.name
    );
    let mut labels = vec![0u16; n];
    ck.log(
        &format!("{how}: mpe"),
        M::state_mpe(s, &mut labels),
        case.mpe,
    );
    let mut out = vec![M::ZERO_ROW; n];
    ck.log(
        &format!("{how}: marginals"),
        M::state_marginals(s, &mut out),
        case.ll,
    );
    if case.ll.is_none() {
        return;
    }
    ck.rows::<M>(&format!("{how}: marginals"), &out, &case.marginals);
    let c = M::NUM_CLASSES;
    for p in 0..n {
        let mut row = M::ZERO_ROW;
        M::state_marginal(s, p, &mut row).unwrap();
        ck.rows::<M>(
            &format!("{how}: state_marginal {p}"),
            &[row],
            &case.marginals[p * c..(p + 1) * c],
        );
    }
}

/// Streaming: `set_all(case 0)`, then `observe` of each row of case 1, answers case 6
/// (their product); clearing every place then answers case 5 (all ones); bad rows and
/// places are refused and change nothing.
fn check_streaming<M: CompiledMap>(ck: &Checker, cases: &[Case])
where
    M::Scalar: Num,
{
    let n = M::NUM_PLACES;
    let mut s = M::NEW_STATE;
    // A fresh state's evidence is a row of ones at every place.
    let fresh = M::state_evidence(&s).iter().flat_map(|r| r.as_ref());
    assert!(
        fresh.map(|v| v.to_f64()).eq(vec![1.0; n * M::NUM_CLASSES]),
        "{}: fresh evidence",
        ck.name
    );
    M::set_all(&mut s, &rows::<M>(&cases[0].evidence)).unwrap();
    for (p, r) in rows::<M>(&cases[1].evidence).iter().enumerate() {
        M::observe(&mut s, p, r).unwrap();
    }
    state_answers::<M>(ck, "observe", &mut s, &cases[6]);
    let before = M::state_log_likelihood(&mut s).unwrap();
    let mut bad = M::ZERO_ROW;
    bad.as_mut()[0] = M::Scalar::from_f64(-1.0);
    assert!(M::observe(&mut s, 0, &bad).is_err(), "{}", ck.name);
    assert!(M::set_evidence(&mut s, 0, &bad).is_err(), "{}", ck.name);
    bad.as_mut()[0] = M::Scalar::from_f64(f64::NAN);
    assert!(M::observe(&mut s, 0, &bad).is_err(), "{}", ck.name);
    assert!(
        M::set_evidence(&mut s, n, &M::ZERO_ROW).is_err(),
        "{}",
        ck.name
    );
    assert!(M::observe(&mut s, n, &M::ZERO_ROW).is_err(), "{}", ck.name);
    assert!(M::clear_evidence(&mut s, n).is_err(), "{}", ck.name);
    assert!(M::set_all(&mut s, &[]).is_err(), "{}", ck.name);
    let after = M::state_log_likelihood(&mut s).unwrap();
    assert_eq!(
        before.to_f64(),
        after.to_f64(),
        "{}: refused input",
        ck.name
    );
    for p in 0..n {
        M::clear_evidence(&mut s, p).unwrap();
    }
    state_answers::<M>(ck, "clear_evidence", &mut s, &cases[5]);
    check_far_label::<M>(ck);
}

/// A label that a fused row reads as 0 counts with its exact value: place 0 observes a
/// row whose class 1 lies at `1e-45` (`f32`: the smallest subnormal, below what a
/// state's row keeps in either family), then a labelled log-likelihood with place 0 of
/// class 1 must equal the stateless one on the same rows (which reads the label's value
/// exactly), not `ZeroLikelihood`.
fn check_far_label<M: CompiledMap>(ck: &Checker)
where
    M::Scalar: Num,
{
    let n = M::NUM_PLACES;
    let mut row = M::ZERO_ROW;
    for (k, v) in row.as_mut().iter_mut().enumerate() {
        *v = M::Scalar::from_f64(if k == 1 { 1e-45 } else { 1.0 });
    }
    let mut e = vec![M::ZERO_ROW; n];
    for r in e.iter_mut() {
        r.as_mut()
            .iter_mut()
            .for_each(|v| *v = M::Scalar::from_f64(1.0));
    }
    e[0] = row;
    let mut labels = vec![u16::MAX; n];
    labels[0] = 1;
    // (`None` where the model rules class 1 out at place 0: both answer
    // `ZeroLikelihood`.)
    let want = M::labelled_log_likelihood(&labels, &e)
        .ok()
        .map(|w| w.to_f64());
    let mut s = M::NEW_STATE;
    M::observe(&mut s, 0, &row).unwrap();
    ck.log(
        "a label observed far below its row's best",
        M::state_labelled_log_likelihood(&mut s, &labels),
        want,
    );
}

#[test]
fn generated_modules_answer_like_their_references() {
    for (name, check, expected) in FIXTURES {
        check(name, expected);
    }
}
