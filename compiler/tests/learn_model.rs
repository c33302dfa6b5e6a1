//! The model file: round trip, determinism, format check, error positions.

mod harness;

use graphspn_compiler::learn::model::MODEL_FORMAT;
use graphspn_compiler::learn::{
    DenseParams, Model, ModelFileError, Progress, TrainingSettings, dense_structure,
    learn_template_spn, uniform_spn,
};
use graphspn_compiler::map::ClassSet;
use graphspn_compiler::spn::Node;
use graphspn_compiler::template::Template;
use harness::learn::*;

fn small_model() -> Model {
    let settings = TrainingSettings {
        epochs: 3,
        seed: 42,
        ..TrainingSettings::default()
    };
    let table = mixture_table(3, 10, 2, 3);
    let samples = sample_table(&table, 3, 10, 2_000, 3);
    let (three, _) = learn_template_spn(
        3,
        10,
        &three_group(),
        &samples,
        &settings,
        1,
        Progress::Hidden,
    )
    .unwrap();
    Model {
        format: MODEL_FORMAT,
        family: Default::default(),
        classes: ClassSet::paper(),
        templates: vec![Template::three(), Template::pair(), Template::singleton()],
        spns: vec![
            three,
            dense_structure(2, 10, &DenseParams::default(), 2).unwrap(),
            uniform_spn(1, 10).unwrap(),
        ],
        settings: settings.to_value(),
        trained_on: vec!["Freiburg/seq1".into()],
    }
}

#[test]
fn save_load_round_trips_exactly() {
    let model = small_model();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.json");
    model.save(&path).unwrap();
    let back = Model::load(&path).unwrap();
    assert_eq!(back, model);
    // Bit-exact weights (PartialEq on f64 would also accept -0.0 == 0.0).
    for (a, b) in model.spns.iter().zip(&back.spns) {
        for (na, nb) in a.nodes.iter().zip(&b.nodes) {
            if let (Node::Sum { weights: wa, .. }, Node::Sum { weights: wb, .. }) = (na, nb) {
                for (x, y) in wa.iter().zip(wb) {
                    assert_eq!(x.to_bits(), y.to_bits());
                }
            }
        }
    }
    // Deterministic output: saving again gives the same bytes.
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(back.to_json().unwrap(), text);
    assert!(text.ends_with('\n'));
    assert!(text.starts_with("{\n  \"format\": 1,"));
    // Settings survive.
    assert_eq!(back.training_settings().unwrap().seed, 42);
    assert_eq!(back.training_settings().unwrap().epochs, 3);
}

#[test]
fn default_settings_are_the_authors() {
    let s = TrainingSettings::default();
    assert_eq!(s.decompositions_per_map, 10);
    assert_eq!(s.structure, DenseParams::default());
    assert_eq!(
        (
            s.structure.decompositions,
            s.structure.subsets,
            s.structure.sums
        ),
        (1, 3, 5)
    );
    assert!(s.structure.balanced);
    assert_eq!(s.epochs, 10);
    assert_eq!((s.smoothing_start, s.smoothing_end), (30.0, 5.0));
    assert_eq!(s.batch_size, 2000);
    assert_eq!(s.symmetry, graphspn_compiler::learn::Symmetry::Tied);
    // Missing fields default; unknown ones are rejected.
    let v: serde_json::Value = serde_json::json!({"epochs": 4});
    assert_eq!(TrainingSettings::from_value(&v).unwrap().epochs, 4);
    let bad: serde_json::Value = serde_json::json!({"epocs": 4});
    assert!(TrainingSettings::from_value(&bad).is_err());
}

#[test]
fn unknown_format_is_rejected_clearly() {
    let text = small_model()
        .to_json()
        .unwrap()
        .replace("\"format\": 1", "\"format\": 99");
    let err = Model::from_json_named(&text, "m.json").unwrap_err();
    assert!(matches!(err, ModelFileError::UnsupportedFormat { .. }));
    let msg = err.to_string();
    assert!(
        msg.contains("m.json") && msg.contains("99") && msg.contains("format 1"),
        "{msg}"
    );
    let err = Model::from_json("{\"classes\": []}").unwrap_err();
    assert!(err.to_string().contains("missing"), "{err}");
}

#[test]
fn errors_name_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.json");
    let mut text = small_model().to_json().unwrap();
    // Break a weight on some line.
    let pos = text.find("\"weights\": [").unwrap() + "\"weights\": [".len();
    text.insert_str(pos, "oops");
    std::fs::write(&path, &text).unwrap();
    let line = text[..pos].lines().count();
    match Model::load(&path).unwrap_err() {
        ModelFileError::Parse {
            source_name,
            line: l,
            column,
            ..
        } => {
            assert!(source_name.ends_with("broken.json"));
            assert_eq!(l, line);
            assert!(column > 0);
        }
        other => panic!("unexpected {other}"),
    }
    let missing = Model::load(dir.path().join("nope.json")).unwrap_err();
    assert!(missing.to_string().contains("nope.json"));
    // Inconsistent models are refused on save.
    let mut m = small_model();
    m.spns.pop();
    assert!(matches!(
        m.save(dir.path().join("x.json")),
        Err(ModelFileError::Invalid { .. })
    ));
    let mut m = small_model();
    if let Node::Sum { weights, .. } = &mut m.spns[1].nodes.last_mut().unwrap() {
        weights[0] = f64::NAN;
    }
    let err = m.to_json().unwrap_err().to_string();
    assert!(err.contains("pair") && err.contains("node"), "{err}");
}

#[test]
fn temperature_tempers_full_tables_exactly_and_one_changes_nothing() {
    use graphspn_compiler::learn::{BadTemperature, temper_spn};
    use graphspn_compiler::spn::Spn;
    let model = small_model();
    // τ = 1: bit for bit the same model (and the same settings record).
    assert_eq!(model.tempered(1.0).unwrap().spns, model.spns);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let mut spn = model.spns[0].clone();
        assert!(matches!(temper_spn(&mut spn, bad), Err(BadTemperature(_))));
        assert!(model.tempered(bad).is_err());
    }
    // A full table (one sum over one product per joint class assignment) tempered by τ
    // is exactly p^τ / Z.
    let table: Spn = dense_structure(2, 10, &DenseParams::default(), 2).unwrap();
    let mut weighted = table.clone();
    let mut k = 0.0;
    for node in &mut weighted.nodes {
        if let Node::Sum { weights, .. } = node {
            for w in weights.iter_mut() {
                k += 1.0;
                *w = k;
            }
            let z: f64 = weights.iter().sum();
            weights.iter_mut().for_each(|w| *w /= z);
        }
    }
    let mut tempered = weighted.clone();
    temper_spn(&mut tempered, 0.5).unwrap();
    let mut ev = graphspn_compiler::interpreter::Evaluator::new(&weighted).unwrap();
    let mut et = graphspn_compiler::interpreter::Evaluator::new(&tempered).unwrap();
    let ones = graphspn_compiler::interpreter::Evidence::from_rows(vec![vec![1.0; 10]; 2]);
    let mut p = Vec::new();
    let mut q = Vec::new();
    for a in 0..10u32 {
        for b in 0..10u32 {
            let fixed = [Some(a), Some(b)];
            p.push(ev.log_likelihood(&fixed, &ones).unwrap().exp());
            q.push(et.log_likelihood(&fixed, &ones).unwrap().exp());
        }
    }
    let z: f64 = p.iter().map(|x| x.sqrt()).sum();
    for (x, y) in p.iter().zip(&q) {
        assert!((x.sqrt() / z - y).abs() < 1e-12, "{x} {y}");
    }
    // The settings record the temperature; training with it gives the same model.
    let t = model.tempered(0.8).unwrap();
    assert_eq!(t.settings["temperature"], serde_json::json!(0.8));
}

/// A model file records the temperature only when it is not 1 (so files of untempered
/// models are unchanged), and reads it back.
#[test]
fn settings_record_a_temperature_only_when_it_is_not_one() {
    let plain = TrainingSettings::default().to_value();
    assert!(plain.get("temperature").is_none(), "{plain}");
    let tempered = TrainingSettings {
        temperature: 0.5,
        ..TrainingSettings::default()
    };
    let v = tempered.to_value();
    assert_eq!(v["temperature"], serde_json::json!(0.5));
    assert_eq!(TrainingSettings::from_value(&v).unwrap().temperature, 0.5);
    assert_eq!(
        TrainingSettings::from_value(&plain).unwrap().temperature,
        1.0
    );
}

/// Each component of the template in a map's decompositions gives one sample; with
/// `add_reversed` each sample of more than one place is preceded by its reverse, and
/// nothing else changes (the same seeds give the same decompositions).
#[test]
fn template_samples_add_reverses_only_when_asked() {
    use graphspn_compiler::learn::template_samples;
    let mut m = harness::codegen::map(
        7,
        3,
        &[(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 6), (1, 4)],
    );
    for (i, p) in m.graph.node_weights_mut().enumerate() {
        p.class = Some((i % 3) as u16);
    }
    let plain = TrainingSettings {
        decompositions_per_map: 4,
        seed: 7,
        ..TrainingSettings::default()
    };
    let reversed = TrainingSettings {
        add_reversed: true,
        ..plain.clone()
    };
    let templates = [Template::three(), Template::pair(), Template::singleton()];
    for (t, template) in templates.iter().enumerate() {
        let maps = std::slice::from_ref(&m);
        let once = template_samples(maps, template, t, &plain).unwrap();
        let twice = template_samples(maps, template, t, &reversed).unwrap();
        assert!(!once.is_empty(), "{}", template.name);
        assert!(once.iter().all(|s| s.len() == template.num_nodes));
        if template.num_nodes == 1 {
            assert_eq!(twice, once, "a single place has no reverse");
            continue;
        }
        assert_eq!(twice.len(), 2 * once.len(), "{}", template.name);
        for (pair, s) in twice.chunks(2).zip(&once) {
            let rev: Vec<_> = s.iter().rev().copied().collect();
            assert_eq!((&pair[0], &pair[1]), (&rev, s), "{}", template.name);
        }
    }
}

/// The smoothing schedule runs linearly from its start (first epoch) to its end (last
/// epoch), and stays at the start for a single epoch.
#[test]
fn smoothing_runs_linearly_from_start_to_end() {
    let s = TrainingSettings {
        epochs: 5,
        smoothing_start: 30.0,
        smoothing_end: 10.0,
        ..TrainingSettings::default()
    };
    let schedule: Vec<f64> = (0..6).map(|e| s.smoothing(e)).collect();
    assert_eq!(schedule, [30.0, 25.0, 20.0, 15.0, 10.0, 10.0]);
    let one = TrainingSettings {
        epochs: 1,
        ..s.clone()
    };
    assert_eq!(one.smoothing(0), 30.0);
}

/// A template that matches nowhere in the training maps is refused by name before
/// any learning; the singleton needs no samples (its SPN is the class prior).
#[test]
fn a_template_matching_nowhere_is_named() {
    use graphspn_compiler::learn::{Progress, TrainModelError, train_model};
    // A path: no place has four neighbours, so no Star fits.
    let mut m = harness::codegen::map(4, 3, &[(0, 1), (1, 2), (2, 3)]);
    for (i, p) in m.graph.node_weights_mut().enumerate() {
        p.class = Some((i % 3) as u16);
    }
    let maps = std::slice::from_ref(&m);
    let settings = TrainingSettings {
        epochs: 1,
        ..TrainingSettings::default()
    };
    let with_star = [Template::star(), Template::pair(), Template::singleton()];
    match train_model(maps, &with_star, &settings, Progress::Hidden) {
        Err(e @ TrainModelError::NoSamples { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains("template \"star\" (5 places joined by 4 edges) matched nowhere")
                    && msg.contains("--family tree-mixture"),
                "{msg}"
            );
        }
        other => panic!("expected NoSamples(\"star\"), got {:?}", other.err()),
    }
    let without = [Template::pair(), Template::singleton()];
    let (model, _) = train_model(maps, &without, &settings, Progress::Hidden).unwrap();
    assert_eq!(model.spns.len(), 2);
}

/// The dense structure's counts are checked with the other training settings, each
/// against its domain and named under `structure`.
#[test]
fn structure_counts_out_of_their_domain_are_refused_by_name() {
    type Case = (fn(&mut DenseParams), &'static str);
    let cases: [Case; 3] = [
        (|p| p.decompositions = 17, "structure.decompositions"),
        (|p| p.subsets = 1, "structure.subsets"),
        (|p| p.sums = 0, "structure.sums"),
    ];
    for (mutate, name) in cases {
        let mut s = TrainingSettings::default();
        mutate(&mut s.structure);
        let err = s.check().expect_err(name);
        assert_eq!(err.setting, name);
    }
    assert!(TrainingSettings::default().check().is_ok());
}
