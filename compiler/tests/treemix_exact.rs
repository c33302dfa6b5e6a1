//! Tree mixtures: the host evaluator (`TreeInstance`) and the interpreter on the
//! explicit instance SPN against brute-force enumeration on maps of at most 8 places,
//! for every query; the forests (spanning, covering, centred); the model file.

mod harness;

use graphspn_compiler::family::{AnyModel, ModelFamily};
use graphspn_compiler::interpreter::{Evaluator, Evidence};
use graphspn_compiler::map::{ClassId, TopoMap, cold};
use graphspn_compiler::spn::Mixing;
use graphspn_compiler::treemix::{
    SpanningTrees, TreeInstance, TreeMixture, TreeTraining, instance_spn, train_tree_mixture,
};
use harness::instance::tiny_map;
use harness::treemix::{oracle, random_model};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

/// Random evidence rows with some exact zeros and tiny values, each with some mass.
fn rows(n: usize, c: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| {
            let mut r: Vec<f64> = (0..c)
                .map(|_| match rng.random_range(0..6) {
                    0 => 0.0,
                    1 => 1e-30,
                    _ => rng.random::<f64>(),
                })
                .collect();
            if r.iter().all(|&x| x == 0.0) {
                r[0] = 0.5;
            }
            r
        })
        .collect()
}

#[test]
fn every_query_matches_enumeration_and_the_interpreter() {
    let (mut checked, mut largest) = (0, 0);
    for seed in 0..60u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = rng.random_range(1..=8);
        let c = rng.random_range(2..=3);
        let t = rng.random_range(1..=4);
        let gamma = rng.random_range(1..=3);
        let map = tiny_map(n, c, seed);
        let model = random_model(c, t, gamma, Mixing::Posterior, seed);
        let trees = SpanningTrees::covering(&map, t, seed).unwrap();
        let mut inst = TreeInstance::build(&model, &map, trees.clone()).unwrap();
        let ev = rows(n, c, &mut rng);
        inst.set_all_evidence(&ev).unwrap();
        let none = vec![None; n];
        let o = oracle(&model, &trees, &ev, &none);
        let tag = format!("seed {seed}: n={n} c={c} T={t} γ={gamma}");
        // Log-likelihood.
        let ll = inst.log_likelihood().unwrap();
        assert!(
            close(ll, o.log_likelihood, 1e-9),
            "{tag}: ll {ll} vs {}",
            o.log_likelihood
        );
        // Marginals, both mixings, and the posterior weights.
        let m = inst.marginals_mixed(Mixing::Posterior).unwrap();
        let a = inst.marginals_mixed(Mixing::Average).unwrap();
        assert!(
            close(m.mixed.log_likelihood, o.log_likelihood, 1e-9),
            "{tag}"
        );
        for v in 0..n {
            for k in 0..c {
                assert!(
                    (m.mixed.probs[v][k] - o.posterior[v][k]).abs() < 1e-9,
                    "{tag}: posterior"
                );
                assert!(
                    (a.mixed.probs[v][k] - o.average[v][k]).abs() < 1e-9,
                    "{tag}: average"
                );
            }
        }
        for (w, x) in m.posterior_weights.iter().zip(&o.weights) {
            assert!((w - x).abs() < 1e-9, "{tag}: weights {w} vs {x}");
        }
        // MPE: the value and the value its labelling attains.
        let mpe = inst.mpe(&none).unwrap();
        assert!(
            close(mpe.log_max_product, o.log_max_product, 1e-9),
            "{tag}: mpe"
        );
        // Labelled: a random partial labelling.
        let fixed: Vec<Option<ClassId>> = (0..n)
            .map(|_| {
                rng.random_bool(0.5)
                    .then(|| rng.random_range(0..c) as ClassId)
            })
            .collect();
        let of = oracle(&model, &trees, &ev, &fixed);
        match inst.log_likelihood_labelled(&fixed) {
            Ok(l) => assert!(close(l, of.log_likelihood, 1e-9), "{tag}: labelled"),
            Err(e) => assert_eq!(of.log_likelihood, f64::NEG_INFINITY, "{tag}: {e}"),
        }
        // The interpreter on the explicit instance SPN (tempered evidence).
        let spn = instance_spn(&inst).unwrap();
        spn.validate().expect("the instance SPN is normalised");
        let mut eval = Evaluator::new(&spn).unwrap();
        let e = Evidence::from_rows(inst.tempered_evidence());
        let free = vec![None; n];
        let im = eval.marginals(&free, &e).unwrap();
        assert!(
            close(im.log_likelihood, o.log_likelihood, 1e-9),
            "{tag}: interpreter ll"
        );
        for v in 0..n {
            for k in 0..c {
                assert!(
                    (im.probs[v][k] - o.posterior[v][k]).abs() < 1e-9,
                    "{tag}: interpreter marginals"
                );
            }
        }
        let ip = eval.mpe(&free, &e).unwrap();
        assert!(
            close(ip.log_max_product, o.log_max_product, 1e-9),
            "{tag}: interpreter mpe"
        );
        let fixed_u32: Vec<Option<u32>> = fixed.iter().map(|f| f.map(u32::from)).collect();
        if let Ok(l) = eval.log_likelihood(&fixed_u32, &e) {
            assert!(
                close(l, of.log_likelihood, 1e-9),
                "{tag}: interpreter labelled"
            );
        }
        checked += 1;
        largest = largest.max(n);
    }
    assert_eq!(checked, 60);
    assert_eq!(largest, 8, "the draws reach 8-place maps");
}

#[test]
fn the_mpe_labelling_attains_its_value() {
    for seed in 0..30u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
        let n = rng.random_range(2..=7);
        let map = tiny_map(n, 3, seed);
        let model = random_model(3, 3, 2, Mixing::Posterior, seed);
        let mut inst = TreeInstance::with_covering_trees(&model, &map, seed).unwrap();
        inst.set_all_evidence(&rows(n, 3, &mut rng)).unwrap();
        let mpe = inst.mpe(&vec![None; n]).unwrap();
        // The labelling's exact likelihood is at least the best single forest's share.
        assert!(mpe.log_probability >= mpe.log_max_product, "seed {seed}");
        let fixed: Vec<Option<ClassId>> =
            mpe.assignment.iter().map(|&k| Some(k as ClassId)).collect();
        let l = inst.log_likelihood_labelled(&fixed).unwrap();
        assert!(close(l, mpe.log_probability, 1e-12));
        // An empty labelling is "none labelled", as the GraphSPN evaluators take it.
        assert_eq!(inst.mpe(&[]).unwrap(), mpe, "seed {seed}");
        assert_eq!(
            inst.log_likelihood_labelled(&[]).unwrap(),
            inst.log_likelihood().unwrap()
        );
        assert!(
            inst.mpe(&fixed[1..]).is_err(),
            "a short labelling is refused"
        );
    }
}

/// Longest path length from `root` in the forest given by parents.
fn height_from(map: &TopoMap, edges: &[(u32, u32)], root: usize) -> usize {
    let n = map.num_places();
    let mut adj = vec![vec![]; n];
    for &(a, b) in edges {
        adj[a as usize].push(b as usize);
        adj[b as usize].push(a as usize);
    }
    let mut dist = vec![usize::MAX; n];
    dist[root] = 0;
    let mut q = std::collections::VecDeque::from([root]);
    let mut h = 0;
    while let Some(v) = q.pop_front() {
        h = h.max(dist[v]);
        for &w in &adj[v] {
            if dist[w] == usize::MAX {
                dist[w] = dist[v] + 1;
                q.push_back(w);
            }
        }
    }
    h
}

#[test]
fn forests_span_every_component_rooted_at_their_centres() {
    for seed in 0..40u64 {
        let n = 1 + (seed as usize % 30);
        let map = tiny_map(n, 2, seed);
        let trees = SpanningTrees::covering(&map, 3, seed).unwrap();
        trees.check_fits(&map).unwrap();
        for f in &trees.forests {
            let edges = f.edges();
            assert_eq!(edges.len(), n - map.connected_components().len());
            let mut seen = vec![false; n];
            for &v in &f.order {
                assert!(!seen[v as usize], "place twice in the order");
                seen[v as usize] = true;
                let p = f.parent[v as usize];
                if p != u32::MAX {
                    assert!(seen[p as usize], "parent after child");
                    assert_eq!(f.depth[v as usize], f.depth[p as usize] + 1);
                }
            }
            // The root minimises the height of its tree.
            for r in f.roots() {
                let h = height_from(&map, &edges, r as usize);
                let best = (0..n)
                    .filter(|&v| {
                        map.connected_components()
                            .iter()
                            .any(|c| c.contains(&v) && c.contains(&(r as usize)))
                    })
                    .map(|v| height_from(&map, &edges, v))
                    .min()
                    .unwrap();
                assert_eq!(h, best, "seed {seed}: root {r} is not a centre");
            }
        }
        // Deterministic.
        assert_eq!(trees, SpanningTrees::covering(&map, 3, seed).unwrap());
    }
}

#[test]
fn a_few_forests_cover_every_edge_of_every_cold_map() {
    let data = cold::data_dir(None);
    let mut worst = 0;
    for b in cold::BUILDINGS {
        for map in cold::load_building(&data, b).unwrap() {
            let need = (1..=8)
                .find(|&t| {
                    let trees = SpanningTrees::covering(&map, t, 0).unwrap();
                    let (covered, all) = trees.coverage(&map);
                    covered == all
                })
                .unwrap_or_else(|| panic!("{}: 8 forests do not cover every edge", map.name));
            worst = worst.max(need);
        }
    }
    assert!(
        worst <= 4,
        "some map needs {worst} forests to cover its edges"
    );
}

#[test]
fn the_model_file_round_trips_and_every_bad_field_is_named() {
    let maps: Vec<TopoMap> = cold::load_building(cold::data_dir(None), "Freiburg").unwrap();
    let model = train_tree_mixture(&maps[..4], &TreeTraining::default()).unwrap();
    let text = model.to_json().unwrap();
    assert!(text.contains("\"family\": \"tree_mixture\""));
    let back = TreeMixture::from_json_named(&text, "m.json").unwrap();
    assert_eq!(back, model);
    match AnyModel::from_json_named(&text, "m.json").unwrap() {
        AnyModel::TreeMixture(m) => assert_eq!(m, model),
        other => panic!("wrong family {:?}", other.family()),
    }
    // An old GraphSPN model file (no family field) still loads as a GraphSPN.
    let demo =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../generated/demo/model.json");
    let old = std::fs::read_to_string(&demo).unwrap();
    assert!(!old.contains("\"family\""));
    assert_eq!(
        AnyModel::load(&demo).unwrap().family(),
        ModelFamily::Graphspn
    );
    // A GraphSPN-only reader refuses a tree mixture, naming the family.
    let e = graphspn_compiler::learn::Model::from_json_named(&text, "m.json").unwrap_err();
    assert!(e.to_string().contains("tree_mixture"), "{e}");
    // Bad fields, each named.
    let bad = |f: &dyn Fn(&mut serde_json::Value), want: &str| {
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        f(&mut v);
        let e = AnyModel::from_json_named(&v.to_string(), "m.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.json") && e.contains(want),
            "{e} (wanted {want:?})"
        );
    };
    bad(
        &|v| v["potential"][1] = serde_json::json!(7.5),
        "not symmetric",
    );
    bad(
        &|v| v["potential"][0] = serde_json::json!(0.0),
        "potential entry 0",
    );
    bad(
        &|v| v["unary"][3] = serde_json::json!(-1.0),
        "unary entry 3",
    );
    bad(
        &|v| v["unary"] = serde_json::json!([1.0]),
        "unary has 1 entries",
    );
    bad(
        &|v| v["evidence_exponent"] = serde_json::json!(0),
        "evidence_exponent",
    );
    bad(
        &|v| v["trees"] = serde_json::json!(0),
        "trees = 0: must be from 1 to 64",
    );
    bad(
        &|v| v["family"] = serde_json::json!("forest"),
        "unknown model family",
    );
    bad(&|v| v["extra"] = serde_json::json!(1), "unknown field");
}

/// A map whose public graph was changed after `TopoMap::new` checked it (a self-loop,
/// an edge twice, ids out of order, a class index past the classes) is refused by the
/// one check every model family runs, with what breaks; a tree mixture's evaluator
/// (which otherwise answered) says so too.
#[test]
fn a_graph_broken_after_construction_is_refused_by_every_family() {
    use graphspn_compiler::map::{MapFitError, Place};
    let model = random_model(2, 2, 1, Mixing::Posterior, 3);
    let classes = model.classes.clone();
    let place = |id: u32| Place {
        id,
        class: Some(0),
        placeholder: false,
        x: 0.0,
        y: 0.0,
    };
    let good = TopoMap::new(
        "m",
        classes.clone(),
        vec![place(1), place(2), place(3)],
        vec![(1, 2), (2, 3)],
    )
    .unwrap();
    good.check_labellable(&classes).unwrap();
    let mut broken: Vec<(TopoMap, &str)> = Vec::new();
    let mut m = good.clone();
    let a = m.graph.node_indices().next().unwrap();
    m.graph.add_edge(a, a, ());
    broken.push((m, "place 1 has an edge to itself"));
    let mut m = good.clone();
    let (a, b) = (
        m.graph.node_indices().next().unwrap(),
        m.graph.node_indices().nth(1).unwrap(),
    );
    m.graph.add_edge(b, a, ());
    broken.push((m, "the edge between places 1 and 2 is there twice"));
    let mut m = good.clone();
    m.graph.node_weights_mut().next().unwrap().id = 5;
    broken.push((m, "id 5 at index 0 is followed by id 2"));
    let mut m = good.clone();
    m.graph.node_weights_mut().nth(2).unwrap().class = Some(2);
    broken.push((m, "place 3 (index 2) has class index 2 of 2 classes"));
    for (m, what) in &broken {
        let err = m.check_labellable(&classes).unwrap_err();
        assert!(matches!(err, MapFitError::Malformed { .. }), "{err}");
        assert!(err.to_string().contains(what), "{err} lacks {what}");
        let err = TreeInstance::with_covering_trees(&model, m, 0).unwrap_err();
        assert!(err.to_string().contains(what), "{err}");
    }
}
