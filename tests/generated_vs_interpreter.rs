//! Differential tests: generated code against the interpreter evaluating the
//! instance GraphSPN, on the demo map (in process, through `graphspn-generated`)
//! and on real COLD maps (compiled into one temporary crate). Seeds are printed.
//!
//! Scale up (see README "Tests"):
//! - `GRAPHSPN_MAX_PLACES=N`: compile COLD maps up to N places (default [`MAX_PLACES`]);
//! - `GRAPHSPN_ALL_MAPS=1`: all 90 COLD maps, no size cap;
//! - `GRAPHSPN_DIFF_VECTORS=N`: evidence vectors per map (default [`VECTORS`] on the
//!   demo map, [`COLD_VECTORS`] on each COLD map).

mod harness;

use std::path::{Path, PathBuf};

use graphspn::codegen::Builder;
use graphspn::decompose::{DecompositionParams, decompose_best};
use graphspn::learn::Model;
use graphspn::map::cold;
use graphspn_generated::demo_floor;
use harness::{
    Case, Variant, case_evidence, check_case, differential, env_usize, in_process_answers,
};

/// Largest COLD map compiled unless `GRAPHSPN_MAX_PLACES` lowers it: no cap by default.
const MAX_PLACES: usize = usize::MAX;
/// Evidence vectors on the demo map.
const VECTORS: usize = 10_000;
/// Evidence vectors per COLD map: the interpreter's side (3 M edges at 230 places)
/// is most of this test's time, which CI must keep well under its budget; raise with
/// `GRAPHSPN_DIFF_VECTORS` for a deeper run.
const COLD_VECTORS: usize = 1_000;

/// The COLD maps tested by default (the largest, Saarbrücken seq2_night1, included),
/// subject to [`MAX_PLACES`].
const COLD_MAPS: &[&str] = &[
    "Saarbrucken/seq3_cloudy1",
    "Saarbrucken/seq3_night2",
    "Saarbrucken/seq1_cloudy2",
    "Saarbrucken/seq4_night3",
    "Saarbrucken/seq2_night1",
    "Freiburg/seq1_cloudy1",
    "Freiburg/seq2_sunny1",
    "Freiburg/seq3_cloudy1",
    "Stockholm/floor4_night_a1",
    "Saarbrucken/seq3_sunny1",
];

fn demo_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/demo")
}

fn demo_model() -> Model {
    Model::load(demo_dir().join("model.json")).unwrap()
}

#[test]
fn demo_floor_matches_interpreter() {
    // The same inputs and decomposition settings as generated/build.rs.
    let inputs = Builder::new(demo_dir().join("model.json"), demo_dir().join("floor.json"))
        .seed(0)
        .count(5)
        .load()
        .unwrap();
    assert_eq!(inputs.decompositions.len(), demo_floor::NUM_DECOMPOSITIONS);
    assert_eq!(inputs.map.num_places(), demo_floor::NUM_PLACES);
    let ids: Vec<u32> = inputs.map.places().map(|p| p.id).collect();
    assert_eq!(ids, demo_floor::PLACE_IDS);
    let case = Case {
        name: "demo_floor".into(),
        model: inputs.model,
        map: inputs.map,
        decs: inputs.decompositions,
        variants: vec![Variant::F32],
        vectors: env_usize("GRAPHSPN_DIFF_VECTORS", VECTORS),
        seed: 1,
    };
    let evs = case_evidence(&case);
    let vals = in_process_answers::<demo_floor::Map>(&evs);
    check_case(&case, &evs, &[vals]);
    eprintln!(
        "demo_floor: {} vectors (seed {}) agree with the interpreter",
        evs.len(),
        case.seed
    );
}

#[test]
fn cold_maps_match_interpreter() {
    let data = graphspn::map::cold::data_dir(None);
    assert!(data.is_dir(), "{} is not a folder", data.display());
    let all = std::env::var_os("GRAPHSPN_ALL_MAPS").is_some();
    let cap = if all {
        usize::MAX
    } else {
        env_usize("GRAPHSPN_MAX_PLACES", MAX_PLACES)
    };
    let vectors = env_usize("GRAPHSPN_DIFF_VECTORS", COLD_VECTORS);
    let model = demo_model();
    let mut paths: Vec<PathBuf> = Vec::new();
    if all {
        for b in cold::BUILDINGS {
            paths.extend(cold::sequence_dirs(data.join(b)).unwrap());
        }
    } else {
        paths.extend(COLD_MAPS.iter().map(|m| data.join(m)));
    }
    let mut cases = Vec::new();
    for (i, path) in paths.iter().enumerate() {
        let map = cold::load_sequence(path).unwrap_or_else(|e| panic!("{e}"));
        if map.num_places() > cap {
            eprintln!(
                "{}: {} places > {cap}, not compiled (raise GRAPHSPN_MAX_PLACES)",
                path.display(),
                map.num_places()
            );
            continue;
        }
        let seed = 100 + i as u64;
        let decs = decompose_best(
            &map,
            &model.templates,
            &DecompositionParams {
                seed,
                ..DecompositionParams::default()
            },
        )
        .unwrap();
        // The first compiled map is checked in all five forms (f32 / f64, scalar as on
        // microcontrollers / SIMD lane groups as on the host, the fixed-point kernel of
        // targets without an FPU), the others alternately in f32 scalar with both
        // kernels and f32 SIMD, against the same interpreter results.
        let variants = if cases.is_empty() {
            vec![
                Variant::F32,
                Variant::F64,
                Variant::F32_SCALAR,
                Variant::F64_SCALAR,
                Variant::FIXED,
            ]
        } else if cases.len() % 2 == 1 {
            vec![Variant::F32_SCALAR, Variant::FIXED]
        } else {
            vec![Variant::F32]
        };
        cases.push(Case {
            name: module_name(path).to_lowercase(),
            model: model.clone(),
            map,
            decs,
            variants,
            vectors,
            seed,
        });
    }
    assert!(!cases.is_empty(), "no COLD map under the size cap {cap}");
    differential("cold_diff", &cases);
}

fn module_name(path: &Path) -> String {
    let mut parts: Vec<String> = path
        .components()
        .rev()
        .take(2)
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    parts.reverse();
    parts.join("_")
}
