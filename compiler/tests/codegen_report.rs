//! The generator's report (`CodeReport`) on the shipped demo maps: the figures the
//! README quotes and the layout properties they rest on.

mod harness;

use std::path::PathBuf;

use graphspn_compiler::codegen::{
    Builder, CodegenOptions, Vectorisation, generate_trees_with_report,
};
use graphspn_compiler::map::{MapFitError, TopoMap};
use graphspn_compiler::treemix::{NO_PARENT, SpanningTrees, TreeMixError, TreeMixture};

/// The demo model on demo map `file` with 5 decompositions, seed 0.
fn builder(file: &str, v: Vectorisation) -> Builder {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../generated/demo");
    Builder::new(dir.join("model.json"), dir.join(file))
        .vectorisation(v)
        .seed(0)
        .count(5)
}

/// Source and report of [`builder`]'s module.
fn generate(b: &Builder) -> (String, graphspn_compiler::codegen::CodeReport) {
    b.report_from(&b.load().expect("demo inputs"))
        .expect("generation")
}

fn demo(file: &str, v: Vectorisation) -> graphspn_compiler::codegen::CodeReport {
    generate(&builder(file, v)).1
}

/// The demo tree mixture on demo map `file` with its spanning forests (seed 0), and a
/// generator of its module and report for a vectorisation and stack budget.
struct DemoTrees {
    model: TreeMixture,
    map: TopoMap,
    forests: SpanningTrees,
}

impl DemoTrees {
    fn new(file: &str) -> Self {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../generated/demo");
        let model = TreeMixture::load(dir.join("tree_model.json")).unwrap();
        let map = TopoMap::load(dir.join(file)).unwrap();
        let forests = SpanningTrees::covering(&map, model.trees, 0).unwrap();
        DemoTrees {
            model,
            map,
            forests,
        }
    }

    fn generate(
        &self,
        v: Vectorisation,
        budget: Option<usize>,
    ) -> (String, graphspn_compiler::codegen::CodeReport) {
        let options = CodegenOptions {
            vectorisation: v,
            max_stack_bytes: budget,
            ..Default::default()
        };
        generate_trees_with_report(&self.model, &self.map, &self.forests, &options)
            .expect("generation")
    }
}

/// A streaming update evaluates the components containing the place in lane groups
/// assembled on the fly, one per template (the D ≤ 8 components of one template fit
/// one group): about 2 groups per update on these maps, where the static groups of
/// neighbouring components gave 2.4 and groups in the decompositions' order 4.3-4.5.
#[test]
fn a_state_update_touches_few_lane_groups() {
    for file in ["floor.json", "saarbrucken_seq2_night1.json"] {
        let r = demo(file, Vectorisation::Simd);
        assert_eq!(r.lanes, 8);
        assert!(
            r.units_per_update <= 2.2,
            "{file}: an update re-evaluates {:.2} lane groups on average",
            r.units_per_update
        );
        // Scalar code evaluates single components: at most one per decomposition.
        let s = demo(file, Vectorisation::Scalar);
        assert!(
            s.units_per_update <= 5.0 && s.units_per_update >= 1.0,
            "{file}: {s:?}"
        );
    }
}

/// With the defaults the 230-place map needs at most 16 KiB of stack per call in
/// scalar (microcontroller) code, its per-map tables are small, and a streaming
/// update costs a small fraction of a full `marginals`.
#[test]
fn scalar_code_of_the_largest_cold_map_fits_a_small_stack() {
    let r = demo("saarbrucken_seq2_night1.json", Vectorisation::Scalar);
    for s in [
        r.stack_log_likelihood,
        r.stack_marginals,
        r.stack_mpe,
        r.stack_state,
    ] {
        assert!(s <= 16 * 1024, "{r:?}");
    }
    // `State::mpe` and `State::labelled_log_likelihood` run the stateless passes.
    assert!(
        r.stack_state >= r.stack_mpe.max(r.stack_log_likelihood),
        "{r:?}"
    );
    assert!(r.table_bytes < 64 * 1024, "{r:?}");
    assert!(r.macs_observe_marginals * 10 < r.macs_marginals, "{r:?}");
}

/// The block templates' terms are grouped by a shared factor (`codegen/sparse`):
/// on the 230-place map the scalar code's multiply(-add)s per call are 258,859 for the
/// log-likelihood, 932,660 for the marginals and 331,663 for MPE, against 352,035,
/// 1,468,780 and 424,839 with one product and one multiply-add per term.
#[test]
fn grouped_terms_cut_the_multiply_adds() {
    let r = demo("saarbrucken_seq2_night1.json", Vectorisation::Scalar);
    assert!(r.macs_log_likelihood <= 300_000, "{r:?}");
    assert!(r.macs_marginals <= 1_100_000, "{r:?}");
    assert!(r.macs_mpe <= 380_000, "{r:?}");
}

/// The body of `pub fn <name>`: from its signature to the next `pub fn`.
fn body<'a>(src: &'a str, name: &str) -> &'a str {
    let start = src.find(&format!("pub fn {name}(")).expect(name);
    let rest = &src[start + 1..];
    &rest[..rest.find("pub fn").unwrap_or(rest.len())]
}

/// The `marginals` body: from its `_unchecked` signature to the next `pub fn`.
fn marginals_body(src: &str) -> &str {
    body(src, "marginals_unchecked")
}

/// SIMD `marginals` evaluates every component once (`eval_group` with the posteriors,
/// no value pass) when its scratch fits the stack budget: at 230 places its
/// multiply-adds are those of the posterior pass alone, and its stack bound includes
/// the scratch. With a budget that only two passes fit, it falls back to them.
#[test]
fn simd_marginals_take_one_pass_when_the_scratch_fits() {
    let b = builder("saarbrucken_seq2_night1.json", Vectorisation::Simd);
    let (src, one) = generate(&b);
    let body = marginals_body(&src);
    assert!(
        body.contains("eval_group") && !body.contains(" values(e, &ALL_UNKNOWN, table"),
        "{body}"
    );

    let (src, two) = generate(&b.max_stack_bytes(one.stack_marginals - 1));
    let body = marginals_body(&src);
    assert!(
        body.contains(" values(e, &ALL_UNKNOWN, table") && body.contains("posterior_pass"),
        "{body}"
    );
    assert_eq!(
        two.macs_marginals,
        one.macs_marginals + one.macs_log_likelihood
    );
    assert!(
        two.stack_marginals + 30_000 < one.stack_marginals,
        "{two:?} {one:?}"
    );
}

/// The stack budget is an upper bound: a module whose worst entry point needs exactly
/// the budget is generated, one byte less is refused with the option named (scalar
/// code, whose plan does not depend on the budget).
#[test]
fn a_stack_budget_equal_to_the_need_is_enough() {
    let b = builder("floor.json", Vectorisation::Scalar);
    let (src, report) = generate(&b);
    let worst = report.worst_stack();
    let (exact, at_budget) = generate(&b.clone().max_stack_bytes(worst));
    assert_eq!(exact, src);
    assert_eq!(at_budget.worst_stack(), worst);
    let err = b
        .max_stack_bytes(worst - 1)
        .report_from(&builder("floor.json", Vectorisation::Scalar).load().unwrap())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&format!("{worst} bytes"))
            && err.contains("`max_stack_bytes`, `--max-stack-bytes` of `graphspn compile`"),
        "{err}"
    );
}

/// Scalar (microcontroller) code takes a value pass and a posterior pass whatever the
/// stack budget: one component at a time, one-pass marginals would keep every
/// component's posteriors on the stack for nothing.
#[test]
fn scalar_marginals_take_two_passes_under_any_budget() {
    let b = builder("floor.json", Vectorisation::Scalar);
    let (src, report) = generate(&b.clone().max_stack_bytes(1 << 30));
    let body = marginals_body(&src);
    assert!(
        body.contains("posterior_pass") && !body.contains("eval_group"),
        "{body}"
    );
    let (default_src, default_report) = generate(&b);
    assert!(src == default_src, "the budget changed the scalar module");
    assert_eq!(report, default_report);
}

/// SIMD entry points scale every evidence row once per call (`scale_rows`), so their
/// gathers are loads: the value passes into a table on the stack (counted in their
/// bounds), one-pass `marginals` into its own output before writing the marginals
/// there. Scalar (microcontroller) code scales each row where it gathers it: no table.
#[test]
fn simd_entry_points_scale_the_evidence_once() {
    let b = builder("saarbrucken_seq2_night1.json", Vectorisation::Simd);
    let (src, r) = generate(&b);
    let (ll, marginals) = (
        body(&src, "labelled_log_likelihood_unchecked"),
        marginals_body(&src),
    );
    assert!(
        ll.contains("scale_rows(e, Some(labels), &mut scaled)"),
        "{ll}"
    );
    assert!(
        marginals.contains("scale_rows(e, None, out)"),
        "{marginals}"
    );
    assert!(r.stack_log_likelihood >= 230 * 10 * 4, "{r:?}");

    let (scalar, _) = generate(&builder(
        "saarbrucken_seq2_night1.json",
        Vectorisation::Scalar,
    ));
    assert!(!scalar.contains("scale_rows("));
    assert!(scalar.contains("let table: Option<&Evidence> = None;"));
}

/// `Builder` picks the fixed-point kernel exactly for targets without an FPU.
#[test]
fn fixed_point_is_chosen_for_targets_without_an_fpu() {
    use graphspn_compiler::codegen::Arithmetic;
    use graphspn_compiler::codegen::Arithmetic::{Fixed, Float};
    for (target, want) in [
        ("thumbv7em-none-eabihf", Float),
        ("thumbv8m.main-none-eabihf", Float),
        ("thumbv7em-none-eabi", Fixed),
        ("thumbv7m-none-eabi", Fixed),
        ("thumbv6m-none-eabi", Fixed),
        ("riscv32imac-unknown-none-elf", Fixed),
        ("riscv32imc-unknown-none-elf", Fixed),
        ("riscv32imafc-unknown-none-elf", Float),
        ("riscv64gc-unknown-none-elf", Float),
        ("x86_64-unknown-linux-gnu", Float),
        ("aarch64-unknown-linux-gnu", Float),
    ] {
        assert_eq!(Arithmetic::for_target(target), want, "{target}");
    }
}

/// The fixed-point kernel: the driver's value and posterior functions of every block
/// template go through the runtime's threshold check (`fx_fwd` / `fx_post`) into a
/// Q0.32 twin, keeping the `f32` functions for small values; MPE stays `f32`. Needs
/// `f32` scalar code: anything else is refused with a message.
#[test]
fn fixed_point_wraps_block_templates_and_refuses_other_forms() {
    use graphspn_compiler::codegen::{Arithmetic, Precision};
    let b = builder("saarbrucken_seq2_night1.json", Vectorisation::Scalar)
        .arithmetic(Arithmetic::Fixed);
    let (src, report) = generate(&b);
    for t in ["t0_star", "t1_three", "t2_pair"] {
        for f in ["fx_fwd", "fx_post", "fl_fwd", "fl_post", "mpe", "max"] {
            assert!(src.contains(&format!("fn {t}_{f}(")), "{t}_{f}");
        }
        assert!(src.contains(&format!("{t}_fx_fwd, {t}_fl_fwd)")), "{t}");
    }
    // Q0.32 constants, no float literal in a fixed-point function.
    let start = src.find("fn t0_star_fx_fwd(").unwrap();
    let body = &src[start..start + src[start..].find("\n}\n").unwrap()];
    assert!(
        body.contains("Fx(0x") && !body.contains("f32"),
        "{}",
        &body[..400]
    );
    let float = demo("saarbrucken_seq2_night1.json", Vectorisation::Scalar);
    assert_eq!(report.macs_log_likelihood, float.macs_log_likelihood);
    // The bound covers what the fixed-point wrapper adds to the largest template's
    // frame: `fx_post`'s Q0.32 rows and adjoints of the Star (5 places, 10 classes).
    let rows = 2 * 5 * 10 * std::mem::size_of::<graphspn_runtime::__private::Fx>();
    assert!(
        report.stack_marginals >= float.stack_marginals + rows,
        "{} vs {} + {rows}",
        report.stack_marginals,
        float.stack_marginals
    );
    for (p, v) in [
        (Precision::F64, Vectorisation::Scalar),
        (Precision::F32, Vectorisation::Simd),
    ] {
        let b = builder("floor.json", v)
            .precision(p)
            .arithmetic(Arithmetic::Fixed);
        let err = b.report_from(&b.load().unwrap()).unwrap_err().to_string();
        assert!(
            err.contains("fixed-point arithmetic needs f32 scalar code"),
            "{err}"
        );
    }
}

/// The tree mixture's evidence factors: on a microcontroller an entry point keeps a
/// table of every place's `φ` (computed once instead of once per forest and pass)
/// exactly when its stack bound with the table fits the budget; SIMD code always does.
/// Scalar code folds `u` into the message matrices, SIMD code keeps it in `φ`.
#[test]
fn tree_factor_tables_follow_the_stack_budget() {
    let demo = DemoTrees::new("saarbrucken_seq2_night1.json");
    let trees = |v: Vectorisation, budget: Option<usize>| demo.generate(v, budget);
    let flags = |src: &str| {
        let start = src.find("FactorCache {").expect("the model's cache flags");
        let end = start + src[start..].find('}').unwrap();
        src[start..end].split_whitespace().collect::<String>()
    };
    // 230 places, 10 classes: the table is 230 · (40 + 4) bytes.
    let table = 230 * 44;
    let (src, r) = trees(Vectorisation::Scalar, None);
    assert_eq!(
        flags(&src),
        "FactorCache{values:true,marginals:false,state:true,",
        "{r:?}"
    );
    assert!(src.contains("folded: true"));
    assert!(r.stack_log_likelihood <= 16 * 1024 && r.stack_mpe <= 16 * 1024);
    // `State::mpe` and `State::labelled_log_likelihood` run the stateless passes.
    assert!(
        r.stack_state >= r.stack_mpe.max(r.stack_log_likelihood),
        "{r:?}"
    );
    // The marginals' stored messages leave no room for the table within 16 KiB.
    assert!(r.stack_marginals + table > 16 * 1024, "{r:?}");
    // One byte less than the MPE bound with the table: the value passes go without.
    let (src, small) = trees(Vectorisation::Scalar, Some(r.stack_mpe - 1));
    assert!(
        flags(&src).starts_with("FactorCache{values:false,"),
        "{small:?}"
    );
    assert_eq!(small.stack_log_likelihood + table, r.stack_log_likelihood);
    assert_eq!(small.stack_mpe + table, r.stack_mpe);
    let (src, _) = trees(Vectorisation::Simd, None);
    assert_eq!(
        flags(&src),
        "FactorCache{values:true,marginals:true,state:true,"
    );
    assert!(src.contains("folded: false"));
}

/// `count(n)` raises the candidate partitions to at least `3n`: the same module as
/// asking for `3n` candidates outright (and not the one the default 15 give).
#[test]
fn count_raises_the_candidates_to_three_times_the_count() {
    let v = Vectorisation::Simd;
    let source = |b: Builder| generate(&b).0;
    let counted = source(builder("floor.json", v).count(10));
    assert!(
        counted == source(builder("floor.json", v).count(10).candidates(30)),
        "count(10) must score 30 candidates"
    );
    assert!(
        counted != source(builder("floor.json", v).count(10).candidates(15)),
        "this map and seed must tell 15 candidates from 30"
    );
}

/// `write_report_from_any` writes the module at the output path and returns the
/// same report as rendering it in memory.
#[test]
fn write_report_from_any_writes_the_module_it_reports() {
    let dir = tempfile::tempdir().unwrap();
    let b = builder("floor.json", Vectorisation::Scalar)
        .module_name("floor")
        .out_dir(dir.path());
    let inputs = b.load_any().expect("demo inputs");
    let (text, report) = b.report_from_any(&inputs).expect("generation");
    let (path, written) = b.write_report_from_any(&inputs).expect("write");
    assert_eq!(path, dir.path().join("floor.rs"));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    assert_eq!(written, report);
    assert!(report.components > 0);
}

/// Tree-mixture generation refuses a map with other classes (another number, or the
/// same in another order), and forests of another map, before emitting anything.
#[test]
fn tree_generation_refuses_inputs_that_do_not_fit() {
    use graphspn_compiler::codegen::CodegenError;
    use graphspn_compiler::map::ClassSet;
    let DemoTrees {
        model,
        map: floor,
        forests: own,
    } = DemoTrees::new("floor.json");
    let others = DemoTrees::new("saarbrucken_seq2_night1.json").forests;
    let options = CodegenOptions::default();
    // `generate_trees` is the module of `generate_trees_with_report`, and an error the
    // same way.
    let (module, _) = generate_trees_with_report(&model, &floor, &own, &options).unwrap();
    assert_eq!(
        graphspn_compiler::codegen::generate_trees(&model, &floor, &own, &options).unwrap(),
        module
    );
    assert!(graphspn_compiler::codegen::generate_trees(&model, &floor, &others, &options).is_err());
    assert!(generate_trees_with_report(&model, &floor, &others, &options).is_err());
    let mut fewer = floor.clone();
    fewer.classes = ClassSet::new(vec!["a".into(), "b".into()]).unwrap();
    assert!(matches!(
        generate_trees_with_report(&model, &fewer, &own, &options),
        Err(CodegenError::TreeInputs(e)) if matches!(*e, TreeMixError::Map(MapFitError::ClassMismatch { .. }))
    ));
    // The same classes in another order are another model's classes.
    let mut swapped = floor.clone();
    let mut names = floor.classes.names().to_vec();
    names.swap(0, 1);
    swapped.classes = ClassSet::new(names).unwrap();
    assert!(matches!(
        generate_trees_with_report(&model, &swapped, &own, &options),
        Err(CodegenError::TreeInputs(e)) if matches!(*e, TreeMixError::Map(MapFitError::ClassMismatch { .. }))
    ));
}

/// The tree mixture's multiply-add counts: every edge of a forest is one message, a
/// `C × C` matrix times a row of `K = ⌈C / lanes⌉` lane vectors (`C · K` lane-vector
/// multiply-adds); `marginals` sends each message up and down, `mpe` adds a backtrack
/// of the largest forest, and a state update re-sends the messages on the paths from
/// the place to its roots (the worst place) before the downward pass.
#[test]
fn tree_multiply_adds_count_one_matrix_row_product_per_message() {
    let demo = DemoTrees::new("floor.json");
    let (forests, map) = (&demo.forests, &demo.map);
    let (n, c) = (map.num_places(), map.classes.len());
    // Edges per forest: its places with a parent, counted from the forests themselves.
    let per_forest: Vec<usize> = forests
        .forests
        .iter()
        .map(|f| f.parent.iter().filter(|&&p| p != NO_PARENT).count())
        .collect();
    let edges: usize = per_forest.iter().sum();
    assert!(edges >= 2 * (n - 1), "{per_forest:?}: spanning forests");
    let worst_path = (0..n)
        .map(|v| {
            forests
                .forests
                .iter()
                .map(|f| f.depth[v] as usize)
                .sum::<usize>()
        })
        .max()
        .unwrap();
    for v in [Vectorisation::Scalar, Vectorisation::Simd] {
        let (_, r) = demo.generate(v, None);
        let mv = c * c.div_ceil(r.lanes);
        if v == Vectorisation::Scalar {
            assert_eq!((r.lanes, mv), (1, c * c));
        }
        assert_eq!(r.macs_log_likelihood, edges * mv, "{v:?}");
        assert_eq!(r.macs_marginals, 2 * edges * mv, "{v:?}");
        let largest = per_forest.iter().max().unwrap();
        assert_eq!(r.macs_mpe, (edges + largest) * mv, "{v:?}");
        assert_eq!(r.macs_observe_marginals, (worst_path + edges) * mv, "{v:?}");
    }
}

/// Every figure of the report on the demo floor, for both model families and both
/// vectorisations, pinned: the stack bounds' margins, the state and table bytes and
/// the multiply-add counts are what firmware budgets and the README rest on, so any
/// change to them must be reviewed (`cargo insta review`), not slip in with a refactor.
#[test]
fn demo_floor_report_figures_are_pinned() {
    let demo_trees = DemoTrees::new("floor.json");
    let trees = |v: Vectorisation, budget: Option<usize>| demo_trees.generate(v, budget).1;
    let mut figures = String::new();
    for v in [Vectorisation::Scalar, Vectorisation::Simd] {
        let spn = demo("floor.json", v);
        let tm = trees(v, None);
        figures += &format!("GraphSPN {v:?}: {spn:#?}\ntree mixture {v:?}: {tm:#?}\n");
    }
    // A 6,400-byte budget keeps the factor table off every scalar tree entry point.
    let small = trees(Vectorisation::Scalar, Some(6400));
    figures += &format!("tree mixture Scalar, 6,400-byte budget: {small:#?}\n");
    insta::assert_snapshot!(figures);
}

/// The report of a module whose templates are compiled node by node (random layered
/// SPNs, linear and log space), pinned like the demo floor's: their stack bounds come
/// from the node count (a value and an adjoint per node, plus spills), not from a plan.
#[test]
fn per_node_report_figures_are_pinned() {
    use graphspn_compiler::codegen::generate_with_report;
    use graphspn_compiler::template::Template;
    use harness::codegen::{decompose, map, model, random_spn};
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let templates = vec![Template::three(), Template::pair(), Template::singleton()];
    let mut figures = String::new();
    // Unnormalised weights with exact zeros take log space.
    for log in [false, true] {
        let spns = templates
            .iter()
            .map(|t| random_spn(&mut rng, t.num_nodes, 3, log, log))
            .collect();
        let m = model(3, templates.clone(), spns);
        let g = map(5, 3, &[(0, 1), (1, 2), (2, 3), (3, 4), (1, 3)]);
        let decs: Vec<_> = (0..2).map(|s| decompose(&g, &m.templates, s)).collect();
        for v in [Vectorisation::Scalar, Vectorisation::Simd] {
            let options = CodegenOptions {
                vectorisation: v,
                ..Default::default()
            };
            let (src, report) = generate_with_report(&m, &g, &decs, &options).unwrap();
            assert!(
                src.contains("let n0 = "),
                "the Three is compiled node by node"
            );
            assert_eq!(src.contains("ln_rows"), log);
            figures += &format!("log space {log}, {v:?}: {report:#?}\n");
        }
    }
    insta::assert_snapshot!(figures);
}

/// A decompositions file gives the module of the decompositions it holds: the same
/// as handing them to the builder in memory.
#[test]
fn a_decompositions_file_gives_the_module_of_its_decompositions() {
    use graphspn_compiler::decompose::{DecompositionParams, decompose_best, file};
    let b = builder("floor.json", Vectorisation::Scalar);
    let inputs = b.load().expect("demo inputs");
    let (model, map) = (&inputs.model, &inputs.map);
    let decs = decompose_best(map, &model.templates, &DecompositionParams::default()).unwrap();
    assert!(!decs.is_empty());
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("decs.json");
    file::save(&path, &decs, map, &model.templates).unwrap();
    // Given decompositions take no drawing options (seed, count): a bare builder.
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../generated/demo");
    let bare = Builder::new(dir.join("model.json"), dir.join("floor.json"))
        .vectorisation(Vectorisation::Scalar);
    let from_file = generate(&bare.clone().decompositions_file(&path));
    let given = generate(&bare.decompositions(decs));
    assert!(from_file.0 == given.0, "the file's module differs");
    assert_eq!(from_file.1, given.1);
}

/// A block template row with an exact-zero weight has floor 0: its floor term is left
/// out (no multiply by zero in the code, none counted), while the template stays in
/// linear space because the other rows of its block cover that tuple.
#[test]
fn an_exact_zero_weight_leaves_its_floor_term_out() {
    use graphspn_compiler::codegen::generate_with_report;
    use graphspn_compiler::spn::Node;
    use harness::codegen::{decompose, dense_model, map};
    let mut m = dense_model(3, false, 1, 7);
    let star = m.templates.iter().position(|t| t.num_nodes == 5).unwrap();
    // The Star's first sum mixes products of two variables' leaves: a lower block.
    let spn = &mut m.spns[star];
    let first = spn.nodes.iter().position(|n| matches!(n, Node::Sum { .. }));
    let Some(Node::Sum { weights, .. }) = first.map(|i| &mut spn.nodes[i]) else {
        panic!("the Star has a sum")
    };
    weights[0] = 0.0;
    let total: f64 = weights.iter().sum();
    weights.iter_mut().for_each(|w| *w /= total);
    let g = map(6, 3, &[(0, 1), (0, 2), (0, 3), (0, 4), (4, 5)]);
    let decs: Vec<_> = (0..2).map(|s| decompose(&g, &m.templates, s)).collect();
    // Multiply-adds of a pass (scalar) or of a lane group (SIMD); with all weights
    // positive the scalar pass counts 1984.
    for (v, macs) in [(Vectorisation::Scalar, 1978), (Vectorisation::Simd, 734)] {
        let options = CodegenOptions {
            vectorisation: v,
            ..Default::default()
        };
        let (src, report) = generate_with_report(&m, &g, &decs, &options).unwrap();
        assert!(!src.contains("ln_rows"), "{v:?}: the Star stays linear");
        assert!(
            !src.contains("let n0 = "),
            "{v:?}: the Star is a block template"
        );
        assert!(
            !src.contains("* V::splat(0.0f32)"),
            "{v:?}: a multiply by zero"
        );
        assert_eq!(report.macs_marginals, macs, "{v:?}");
    }
}

/// The value of `pub const NAME: usize = V;` in generated source `src`.
fn usize_constant(src: &str, name: &str) -> usize {
    let start = src
        .find(&format!("pub const {name}: usize = "))
        .unwrap_or_else(|| panic!("no constant {name}"));
    let rest = &src[start..];
    let value = &rest[rest.find('=').unwrap() + 1..rest.find(';').unwrap()];
    value.trim().parse().expect(name)
}

/// The public size constants of both families' modules state the shape of what was
/// compiled, counted here from the inputs: places, classes, the root mixture's size,
/// lanes, and the components (GraphSPN: distinct template copies over all
/// decompositions; tree mixture: one cached message per tree and place).
#[test]
fn size_constants_count_the_compiled_model() {
    use std::collections::BTreeSet;
    for v in [Vectorisation::Scalar, Vectorisation::Simd] {
        let b = builder("floor.json", v);
        let inputs = b.load().expect("demo inputs");
        let (src, r) = generate(&b);
        let copies: BTreeSet<_> = inputs
            .decompositions
            .iter()
            .flat_map(|d| &d.components)
            .map(|c| (c.template, c.places.clone()))
            .collect();
        let (n, c) = (inputs.map.num_places(), inputs.map.classes.len());
        assert_eq!(usize_constant(&src, "NUM_PLACES"), n);
        assert_eq!(usize_constant(&src, "NUM_CLASSES"), c);
        assert_eq!(usize_constant(&src, "NUM_DECOMPOSITIONS"), 5);
        assert_eq!(usize_constant(&src, "LANES"), r.lanes);
        assert_eq!(
            usize_constant(&src, "NUM_COMPONENTS"),
            copies.len(),
            "{v:?}"
        );
        // Shared copies are what makes the mixture cheap: fewer than the sum of sizes.
        let all: usize = inputs
            .decompositions
            .iter()
            .map(|d| d.components.len())
            .sum();
        assert!(copies.len() < all, "{} of {all}", copies.len());

        let demo = DemoTrees::new("floor.json");
        let (src, r) = demo.generate(v, None);
        let trees = demo.forests.forests.len();
        assert_eq!(trees, demo.model.trees);
        assert_eq!(usize_constant(&src, "NUM_PLACES"), n);
        assert_eq!(usize_constant(&src, "NUM_CLASSES"), c);
        assert_eq!(usize_constant(&src, "NUM_DECOMPOSITIONS"), trees);
        assert_eq!(usize_constant(&src, "LANES"), r.lanes);
        assert_eq!(usize_constant(&src, "NUM_COMPONENTS"), trees * n, "{v:?}");
    }
}

/// A tree mixture with one class, or more than 256, is refused as a model the
/// generator does not compile (not as a bad option), pointing to the interpreter.
#[test]
fn tree_mixtures_outside_the_compiled_class_range_are_unsupported() {
    use graphspn_compiler::codegen::CodegenError;
    use graphspn_compiler::spn::Mixing;
    for c in [1, 257] {
        let model = harness::treemix::random_model(c, 2, 1, Mixing::Average, 3);
        let map = harness::instance::tiny_map(4, c, 3);
        let forests = SpanningTrees::covering(&map, 2, 0).unwrap();
        let err = generate_trees_with_report(&model, &map, &forests, &CodegenOptions::default())
            .unwrap_err();
        assert!(matches!(err, CodegenError::Unsupported(_)), "{c}: {err}");
        assert!(
            err.to_string().contains(&format!(
                "the model cannot be compiled: a tree mixture is compiled for 2 to 256 classes, the model has {c}"
            )),
            "{err}"
        );
    }
}
