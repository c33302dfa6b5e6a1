//! Learning from real COLD maps and querying the instance of a held-out map.
//! Reads the shipped COLD maps (or `$GRAPHSPN_DATA`); fails if they are missing.

use std::path::PathBuf;
use std::sync::OnceLock;

use graphspn_compiler::instance::{Instance, InstanceModel, InstanceParams};
use graphspn_compiler::interpreter::{Evaluator, Evidence};
use graphspn_compiler::learn::{Model, Progress, TemplateTraining, TrainingSettings, train_model};
use graphspn_compiler::map::{TopoMap, cold};
use graphspn_compiler::template::Template;
use proptest::prelude::*;

fn data() -> PathBuf {
    let d = cold::data_dir(None);
    assert!(
        d.join("Freiburg").is_dir(),
        "{} does not hold the COLD maps",
        d.display()
    );
    d
}

fn load(d: &std::path::Path, seq: &str) -> TopoMap {
    cold::load_sequence(d.join(seq)).unwrap_or_else(|e| panic!("loading {seq}: {e}"))
}

const TRAIN: [&str; 3] = [
    "Freiburg/seq1_cloudy1",
    "Saarbrucken/seq1_cloudy1",
    "Saarbrucken/seq3_cloudy1",
];

/// The model, its per-template training reports and the training maps.
type Trained = (Model, Vec<TemplateTraining>, Vec<TopoMap>);

fn trained() -> &'static Trained {
    static MODEL: OnceLock<Trained> = OnceLock::new();
    MODEL.get_or_init(|| {
        let d = data();
        let maps: Vec<TopoMap> = TRAIN.iter().map(|s| load(&d, s)).collect();
        let (model, trainings) = train_model(
            &maps,
            &Template::paper_set(),
            &TrainingSettings::default(),
            Progress::Hidden,
        )
        .unwrap();
        (model, trainings, maps)
    })
}

#[test]
fn training_log_likelihood_rises() {
    let (_, trainings, _) = trained();
    for t in trainings {
        let Some(r) = &t.report else { continue };
        let per_epoch = &r.log_likelihood_per_epoch;
        eprintln!(
            "{}: {} -> {:?}",
            t.template, r.initial_log_likelihood, per_epoch
        );
        assert_eq!(per_epoch.len(), TrainingSettings::default().epochs);
        let last = *per_epoch.last().unwrap();
        assert!(
            last > r.initial_log_likelihood + 0.1,
            "{}: {} -> {last}",
            t.template,
            r.initial_log_likelihood
        );
        assert!(last >= per_epoch[0], "{}: {per_epoch:?}", t.template);
        // Rises over epochs, up to small dips from the decaying smoothing.
        for w in per_epoch.windows(2) {
            assert!(w[1] >= w[0] - 0.02, "{}: {per_epoch:?}", t.template);
        }
    }
}

fn test_map() -> (TopoMap, InstanceModel) {
    let (model, _, _) = trained();
    let map = load(&data(), "Freiburg/seq2_cloudy1");
    let inst = Instance::for_map(model, &map, &InstanceParams::default()).unwrap();
    (map, InstanceModel::new(inst).unwrap())
}

fn certain_rows(map: &TopoMap) -> Vec<Vec<f64>> {
    let c = map.classes.len();
    map.places()
        .map(|p| match p.class {
            Some(k) => (0..c)
                .map(|j| f64::from(u8::from(j == k as usize)))
                .collect(),
            None => vec![1.0 / c as f64; c],
        })
        .collect()
}

#[test]
fn certain_evidence_gives_the_truth() {
    let (map, mut im) = test_map();
    let m = im
        .marginals(&Evidence::from_rows(certain_rows(&map)))
        .unwrap();
    let mut checked = 0;
    for (i, p) in map.places().enumerate() {
        if let Some(k) = p.class {
            for (j, &q) in m.probs[i].iter().enumerate() {
                let want = f64::from(u8::from(j == k as usize));
                assert!((q - want).abs() < 1e-9, "place {}: {:?}", p.id, m.probs[i]);
            }
            checked += 1;
        }
    }
    assert!(checked > 50);
}

/// Conditional class frequencies across edges of the training maps:
/// `co[a][b] = P(neighbour class b | class a)`.
fn co_occurrence(maps: &[TopoMap], c: usize) -> Vec<Vec<f64>> {
    let mut co = vec![vec![0.0; c]; c];
    for m in maps {
        for (a, b) in m.edge_list() {
            if let (Some(x), Some(y)) = (m.place(a).class, m.place(b).class) {
                co[x as usize][y as usize] += 1.0;
                co[y as usize][x as usize] += 1.0;
            }
        }
    }
    for row in &mut co {
        let z: f64 = row.iter().sum();
        if z > 0.0 {
            row.iter_mut().for_each(|x| *x /= z);
        }
    }
    co
}

#[test]
fn a_place_without_evidence_follows_its_neighbours() {
    let (map, mut im) = test_map();
    let (_, _, train_maps) = trained();
    let c = map.classes.len();
    let co = co_occurrence(train_maps, c);
    let cr = map.classes.index_of("CR").unwrap() as usize;
    let dw = map.classes.index_of("DW").unwrap() as usize;
    // Places with at least two neighbours, all labelled with one class.
    let candidates: Vec<(usize, usize)> = (0..map.num_places())
        .filter_map(|i| {
            let nb = map.neighbors(i);
            let k = map.place(*nb.first()?).class?;
            (nb.len() >= 2 && nb.iter().all(|&j| map.place(j).class == Some(k)))
                .then_some((i, k as usize))
        })
        .collect();
    let in_corridor: Vec<usize> = candidates
        .iter()
        .filter(|&&(_, k)| k == cr)
        .map(|&(i, _)| i)
        .take(3)
        .collect();
    let others: Vec<(usize, usize)> = candidates
        .iter()
        .filter(|&&(_, k)| k != cr)
        .copied()
        .take(3)
        .collect();
    assert!(!in_corridor.is_empty());
    let base = certain_rows(&map);
    let query = |im: &mut InstanceModel, i: usize| {
        let mut rows = base.clone();
        rows[i] = vec![1.0 / c as f64; c];
        im.marginals(&Evidence::from_rows(rows)).unwrap().probs[i].clone()
    };
    for &i in &in_corridor {
        let q = query(&mut im, i);
        eprintln!("corridor place {}: {q:?}", map.place(i).id);
        assert!(q[cr] + q[dw] > 0.5, "place {}: {q:?}", map.place(i).id);
    }
    for (i, k) in others
        .into_iter()
        .chain(in_corridor.iter().map(|&i| (i, cr)))
    {
        let q = query(&mut im, i);
        let max = q.iter().cloned().fold(0.0, f64::max);
        assert!(
            max > 1.0 / c as f64 + 0.2,
            "place {}: near-uniform {q:?}",
            map.place(i).id
        );
        let arg = q.iter().position(|&x| x == max).unwrap();
        // The argmax is among the 2 classes most often seen next to class k in training.
        let mut ranked: Vec<usize> = (0..c).collect();
        ranked.sort_by(|&a, &b| co[k][b].total_cmp(&co[k][a]));
        assert!(
            ranked[..2].contains(&arg),
            "place {} (neighbours all {}): argmax {} not among {:?}; {q:?}",
            map.place(i).id,
            map.classes.name(k as u16),
            map.classes.name(arg as u16),
            &ranked[..2]
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Permuting interchangeable template nodes leaves the trained template SPN's value
    /// unchanged.
    #[test]
    fn trained_template_spns_are_symmetric(x in proptest::collection::vec(0u32..10, 5), t in 0usize..3) {
        let (model, _, _) = trained();
        let tpl = &model.templates[t];
        prop_assume!(tpl.num_nodes > 1);
        let spn = &model.spns[t];
        let mut ev = Evaluator::new(spn).unwrap();
        let uniform = Evidence::from_rows(vec![vec![1.0; 10]; tpl.num_nodes]);
        let x = &x[..tpl.num_nodes];
        let fixed: Vec<Option<u32>> = x.iter().map(|&k| Some(k)).collect();
        let base = ev.log_likelihood(&fixed, &uniform).unwrap();
        let autos = tpl.automorphisms();
        prop_assert!(autos.len() > 1);
        for perm in autos {
            let permuted: Vec<Option<u32>> = (0..x.len()).map(|v| Some(x[perm[v]])).collect();
            let v = ev.log_likelihood(&permuted, &uniform).unwrap();
            prop_assert!((v - base).abs() < 1e-9, "{} {:?} vs {:?}: {} vs {}", tpl.name, x, perm, base, v);
        }
    }
}
