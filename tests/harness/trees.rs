//! The tree-mixture side of the shared harness: generated tree-mixture modules (any
//! number, in one temporary crate, run by the same binary as GraphSPN modules) checked
//! against `TreeInstance` (exact, f64) on every vector and against the interpreter on
//! the explicit instance SPN (`instance_spn`, tempered evidence) on a share of them.

use graphspn::codegen::{CodegenOptions, Precision, Vectorisation, generate_trees_with_report};
use graphspn::interpreter::{Evaluator, Evidence};
use graphspn::map::{ClassId, TopoMap};
use graphspn::spn::Mixing;
use graphspn::treemix::{SpanningTrees, TreeInstance, TreeMixture, instance_spn};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::{Prepared, Variant, evidence, probe_labels, run_modules, stride};

/// One map's tree mixture to compile and test (see [`super::Case`]).
pub struct TreeCase {
    /// Module name stem.
    pub name: String,
    /// The model.
    pub model: TreeMixture,
    /// The map.
    pub map: TopoMap,
    /// The spanning trees.
    pub trees: SpanningTrees,
    /// The generated modules.
    pub variants: Vec<Variant>,
    /// Random evidence vectors.
    pub vectors: usize,
    /// Seed of the evidence.
    pub seed: u64,
    /// Every how many vectors the interpreter checks too (it is 3-10x slower than
    /// `TreeInstance`).
    pub interpreter_every: usize,
    /// Every how many vectors (0: none) the rows are scaled by `2^110`, `2^-110` or
    /// `2^-135` in turn (exact but for `f32` subnormals: subnormal `f32` inputs for the
    /// smallest entries, or for whole rows).
    pub extreme_every: usize,
    /// `true`: a 64 KiB stack budget, so every entry point keeps its table of evidence
    /// factors. `false`: scalar variants get their largest stack bound less one table,
    /// so at least the deepest entry point computes `φ` in each pass instead.
    pub factor_tables: bool,
}

impl TreeCase {
    /// Module name of one variant.
    pub fn module(&self, v: &Variant) -> String {
        format!("{}_{}", self.name, v.suffix())
    }

    /// The evidence vectors, rounded through `f32` when some variant is `f32`.
    pub fn evidence(&self) -> Vec<Vec<Vec<f64>>> {
        let (n, c) = (self.map.num_places(), self.model.num_classes());
        let round = self
            .variants
            .iter()
            .any(|v| v.precision == graphspn::codegen::Precision::F32);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        (0..self.vectors)
            .map(|v| {
                let mut e = evidence(&mut rng, n, c, v);
                if self.extreme_every > 0 && v % self.extreme_every == 1 {
                    // 2^-135: the largest entry of an `f32` row is subnormal, so the
                    // evidence factor's exact rescaling needs its two-step form.
                    let s = match (v / self.extreme_every) % 3 {
                        0 => 2f64.powi(110),
                        1 => 2f64.powi(-110),
                        _ => 2f64.powi(-135),
                    };
                    for row in e
                        .iter_mut()
                        .filter(|r| r.iter().all(|&x| x == 0.0 || x > 1e-9))
                    {
                        row.iter_mut().for_each(|x| *x *= s);
                    }
                }
                if round {
                    for x in e.iter_mut().flatten() {
                        *x = *x as f32 as f64;
                    }
                }
                e
            })
            .collect()
    }

    /// The tolerance of one variant's answers: the precision's, plus for fixed-point
    /// messages (targets without an FPU) their bound: `n` messages of relative error
    /// `η` in a forest's value, `2n` in a marginal's numerator and its sum, and the
    /// forests' posterior weights (`6n·η` covers every answer).
    pub fn tolerance(&self, v: &Variant) -> f64 {
        let opts = CodegenOptions {
            precision: v.precision,
            vectorisation: v.vectorisation,
            arithmetic: v.arithmetic,
            max_stack_bytes: Some(1 << 20),
            ..Default::default()
        };
        let (_, r) = generate_trees_with_report(&self.model, &self.map, &self.trees, &opts)
            .unwrap_or_else(|e| panic!("{}: {e}", self.module(v)));
        let n = self.map.num_places() as f64;
        v.tolerance() + r.message_error.map_or(0.0, |eta| 6.0 * n * eta)
    }

    /// The generated source of one variant.
    pub fn source(&self, v: &Variant) -> String {
        // f64 scalar `marginals` of the 230-place map needs 18 KB of message scratch:
        // more than the default 16 KiB budget of scalar code (microcontrollers).
        let opts = |budget: usize| CodegenOptions {
            precision: v.precision,
            vectorisation: v.vectorisation,
            arithmetic: v.arithmetic,
            max_stack_bytes: Some(budget),
            ..Default::default()
        };
        let generate = |budget: usize| {
            generate_trees_with_report(&self.model, &self.map, &self.trees, &opts(budget))
        };
        let (src, r) = generate(64 * 1024).unwrap_or_else(|e| panic!("{}: {e}", self.module(v)));
        if self.factor_tables || v.vectorisation == Vectorisation::Simd {
            return src;
        }
        let (n, c) = (self.map.num_places(), self.model.num_classes());
        let scalar = if v.precision == Precision::F32 { 4 } else { 8 };
        let table = n * (c * scalar + 4);
        let deepest = [
            r.stack_log_likelihood,
            r.stack_marginals,
            r.stack_mpe,
            r.stack_state,
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        // The state's other calls may need more than that budget: then keep the tables.
        generate(deepest - table).map_or(src, |(s, _)| s)
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    a == b || (a - b).abs() <= tol * b.abs().max(1.0)
}

/// Generates, builds and runs every variant of every case in one crate, then checks
/// each against `TreeInstance` and the interpreter ([`check_tree_case`]).
pub fn tree_differential(crate_name: &str, cases: &[TreeCase]) {
    let prepared: Vec<Prepared> = cases
        .iter()
        .map(|case| {
            let modules = case
                .variants
                .iter()
                .map(|v| (case.module(v), case.source(v)))
                .collect();
            (modules, case.evidence())
        })
        .collect();
    let results = run_modules(crate_name, &prepared);
    for ((case, (_, evs)), vals) in cases.iter().zip(&prepared).zip(&results) {
        let start = std::time::Instant::now();
        check_tree_case(case, evs, vals);
        eprintln!(
            "{} ({} variants): {} places, {} trees, {} vectors (seed {}) agree with TreeInstance and the interpreter ({:.1} s)",
            case.name,
            case.variants.len(),
            case.map.num_places(),
            case.trees.len(),
            evs.len(),
            case.seed,
            start.elapsed().as_secs_f64()
        );
    }
}

/// The interpreter's evaluators of a case: the explicit instance SPN (mixture), and
/// one per tree when the model averages the trees' marginals.
struct Interpreters {
    mixture: Evaluator,
    per_tree: Vec<Evaluator>,
}

impl Interpreters {
    fn new(case: &TreeCase) -> Interpreters {
        let spn = |trees: SpanningTrees| {
            let inst = TreeInstance::build(&case.model, &case.map, trees).unwrap();
            Evaluator::new(&instance_spn(&inst).unwrap()).unwrap()
        };
        let per_tree = match case.model.mixing {
            Mixing::Posterior => vec![],
            Mixing::Average => case
                .trees
                .forests
                .iter()
                .map(|f| {
                    spn(SpanningTrees {
                        forests: vec![f.clone()],
                    })
                })
                .collect(),
        };
        Interpreters {
            mixture: spn(case.trees.clone()),
            per_tree,
        }
    }
}

/// Checks the generated answers `vals` (one array per variant, per vector see
/// [`stride`]) against `TreeInstance` on every vector (log-likelihood, marginals mixed
/// as the model says, MPE value, the value the generated labels attain, labelled
/// log-likelihood) and against the interpreter on every `interpreter_every`-th.
pub fn check_tree_case(case: &TreeCase, evs: &[Vec<Vec<f64>>], vals: &[Vec<f64>]) {
    let (n, c) = (case.map.num_places(), case.model.num_classes());
    let stride = stride(n, c);
    let tolerances: Vec<f64> = case.variants.iter().map(|v| case.tolerance(v)).collect();
    let base = TreeInstance::build(&case.model, &case.map, case.trees.clone()).unwrap();
    let interp = Interpreters::new(case);
    let threads = rayon::current_num_threads().max(1);
    let share = evs.len().div_ceil(threads).max(1);
    evs.par_chunks(share).enumerate().for_each(|(part, chunk)| {
        let mut inst = base.clone();
        let mut it = Interpreters {
            mixture: interp.mixture.clone(),
            per_tree: interp.per_tree.clone(),
        };
        for (i, ev) in chunk.iter().enumerate() {
            let v = part * share + i;
            let answers: Vec<(String, f64, &[f64])> = case
                .variants
                .iter()
                .zip(vals)
                .zip(&tolerances)
                .map(|((var, x), &tol)| {
                    assert_eq!(
                        x.len(),
                        evs.len() * stride,
                        "{}: result size",
                        case.module(var)
                    );
                    (case.module(var), tol, &x[v * stride..(v + 1) * stride])
                })
                .collect();
            check_vector(case, &mut inst, ev, v, &answers);
            if v.is_multiple_of(case.interpreter_every.max(1)) {
                check_interpreter(case, &mut it, ev, v, &answers);
            }
        }
    });
}

fn ctx(case: &TreeCase, module: &str, v: usize, ev: &[Vec<f64>]) -> String {
    format!(
        "module {module} seed {} vector {v} (kind {}): evidence {:?}",
        case.seed,
        v % 6,
        ev
    )
}

/// One vector against `TreeInstance`.
fn check_vector(
    case: &TreeCase,
    inst: &mut TreeInstance,
    ev: &[Vec<f64>],
    v: usize,
    answers: &[(String, f64, &[f64])],
) {
    let n = case.map.num_places();
    let c = case.model.num_classes();
    inst.set_all_evidence(ev).unwrap();
    let m = inst.marginals().unwrap();
    let none = vec![None; n];
    let best = inst.mpe(&none).unwrap();
    let probe: Vec<Option<ClassId>> = probe_labels(ev, v)
        .into_iter()
        .map(|l| l.map(|k| k as ClassId))
        .collect();
    let labelled = inst.log_likelihood_labelled(&probe);
    for (name, tol, got) in answers {
        let at = || ctx(case, name, v, ev);
        assert!(
            close(got[0], m.mixed.log_likelihood, *tol),
            "log-likelihood {} vs TreeInstance {}: {}",
            got[0],
            m.mixed.log_likelihood,
            at()
        );
        for p in 0..n {
            for k in 0..c {
                let g = got[3 + n + p * c + k];
                assert!(
                    (g - m.mixed.probs[p][k]).abs() <= *tol,
                    "marginal place {p} class {k}: {g} vs TreeInstance {}: {}",
                    m.mixed.probs[p][k],
                    at()
                );
            }
        }
        assert!(
            close(got[1], best.log_max_product, *tol),
            "mpe value {} vs TreeInstance {}: {}",
            got[1],
            best.log_max_product,
            at()
        );
        let labels: Vec<Option<ClassId>> =
            got[3..3 + n].iter().map(|&x| Some(x as ClassId)).collect();
        let attained = inst.mpe(&labels).unwrap().log_max_product;
        assert!(
            close(attained, best.log_max_product, *tol),
            "the generated mpe labels attain {attained}, not {}: {}",
            best.log_max_product,
            at()
        );
        match &labelled {
            Ok(l) => assert!(
                close(got[2], *l, *tol),
                "labelled log-likelihood {} vs TreeInstance {l}: {}",
                got[2],
                at()
            ),
            Err(_) => assert!(got[2].is_nan(), "labelled: zero likelihood: {}", at()),
        }
    }
}

/// One vector against the interpreter on the explicit instance SPN.
fn check_interpreter(
    case: &TreeCase,
    it: &mut Interpreters,
    ev: &[Vec<f64>],
    v: usize,
    answers: &[(String, f64, &[f64])],
) {
    let n = case.map.num_places();
    let c = case.model.num_classes();
    let gamma = case.model.evidence_exponent as i32;
    let rows: Vec<Vec<f64>> = ev
        .iter()
        .map(|r| r.iter().map(|a| a.powi(gamma)).collect())
        .collect();
    // Rows scaled by 2^-135 to the power γ ≥ 8 underflow the interpreter's linear f64
    // (the generated code and `TreeInstance` keep exact exponents): not comparable.
    if rows.iter().any(|r| r.iter().all(|&a| a == 0.0)) {
        return;
    }
    let tempered = Evidence::from_rows(rows);
    let free = vec![None; n];
    let mix = it.mixture.marginals(&free, &tempered).unwrap();
    let probs = if it.per_tree.is_empty() {
        mix.probs.clone()
    } else {
        let t = it.per_tree.len() as f64;
        let mut avg = vec![vec![0.0; c]; n];
        for e in &mut it.per_tree {
            let m = e.marginals(&free, &tempered).unwrap();
            for (a, r) in avg.iter_mut().zip(&m.probs) {
                for (x, y) in a.iter_mut().zip(r) {
                    *x += y / t;
                }
            }
        }
        avg
    };
    let best = it.mixture.log_max_product(&free, &tempered).unwrap();
    let probe = probe_labels(ev, v);
    let labelled = it.mixture.log_likelihood(&probe, &tempered);
    for (name, tol, got) in answers {
        let at = || ctx(case, name, v, ev);
        assert!(
            close(got[0], mix.log_likelihood, *tol),
            "log-likelihood {} vs interpreter {}: {}",
            got[0],
            mix.log_likelihood,
            at()
        );
        for p in 0..n {
            for k in 0..c {
                let g = got[3 + n + p * c + k];
                assert!(
                    (g - probs[p][k]).abs() <= *tol,
                    "marginal place {p} class {k}: {g} vs interpreter {}: {}",
                    probs[p][k],
                    at()
                );
            }
        }
        assert!(
            close(got[1], best, *tol),
            "mpe value {} vs interpreter {best}: {}",
            got[1],
            at()
        );
        let labels: Vec<Option<u32>> = got[3..3 + n].iter().map(|&x| Some(x as u32)).collect();
        let attained = it.mixture.log_max_product(&labels, &tempered).unwrap();
        assert!(
            close(attained, best, *tol),
            "the generated mpe labels attain {attained} in the interpreter, not {best}: {}",
            at()
        );
        match &labelled {
            Ok(l) => assert!(
                close(got[2], *l, *tol),
                "labelled log-likelihood {} vs interpreter {l}: {}",
                got[2],
                at()
            ),
            Err(_) => assert!(got[2].is_nan(), "labelled: zero likelihood: {}", at()),
        }
    }
}
