//! Differential tests of generated tree-mixture code: every query of the generated
//! module (log-likelihood, marginals, MPE value and the value its labels attain,
//! labelled log-likelihood) against `TreeInstance` (exact, f64) on every evidence
//! vector and against the interpreter on the explicit instance SPN on a share of them;
//! f32 and f64, scalar (the microcontroller form) and SIMD (the host form); evidence
//! with exact zeros, 1e-30 scales, one-hot and uniform rows. The demo floor (through
//! `graphspn-generated`, in process, and in every form in a temporary crate) and COLD
//! maps including the 230-place one; all 90 with `GRAPHSPN_ALL_MAPS=1`. Seeds printed.
//!
//! Scale up: `GRAPHSPN_ALL_MAPS=1`, `GRAPHSPN_DIFF_VECTORS=N` (vectors per COLD map).

mod harness;

use std::path::PathBuf;

use graphspn::codegen::Builder;
use graphspn::map::cold;
use graphspn::treemix::{SpanningTrees, TreeMixture};
use graphspn_generated::demo_floor_trees as floor;
use harness::trees::{TreeCase, check_tree_case};
use harness::{Variant, env_usize, in_process_answers};

/// Evidence vectors per COLD map (the interpreter checks every fourth).
const COLD_VECTORS: usize = 200;
/// Evidence vectors on the demo floor.
const FLOOR_VECTORS: usize = 2_000;

/// The COLD maps tested by default: the largest (230 places) and one of each building.
const COLD_MAPS: &[&str] = &[
    "Saarbrucken/seq2_night1",
    "Freiburg/seq1_cloudy1",
    "Stockholm/floor4_night_a1",
];

fn demo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("generated/demo")
}

fn demo_model() -> TreeMixture {
    TreeMixture::load(demo().join("tree_model.json")).unwrap()
}

/// The demo floor's case with the inputs of `generated/build.rs`.
fn floor_case(variants: Vec<Variant>, vectors: usize) -> TreeCase {
    let inputs = match Builder::new(demo().join("tree_model.json"), demo().join("floor.json"))
        .seed(0)
        .load_any()
        .unwrap()
    {
        graphspn::codegen::AnyInputs::TreeMixture(i) => i,
        _ => panic!("the demo tree model is a tree mixture"),
    };
    TreeCase {
        name: "demo_floor".into(),
        model: inputs.model,
        map: inputs.map,
        trees: inputs.trees,
        variants,
        vectors,
        seed: 1,
        interpreter_every: 4,
        extreme_every: 0,
        factor_tables: true,
    }
}

/// `graphspn-generated`'s module, called in this process, on the checked vectors.
#[test]
fn demo_floor_module_matches_tree_instance_and_interpreter() {
    let case = floor_case(vec![Variant::F32], FLOOR_VECTORS);
    assert_eq!(case.trees.len(), floor::NUM_TREES);
    assert_eq!(floor::MODEL_FAMILY, "tree_mixture");
    let ids: Vec<u32> = case.map.places().map(|p| p.id).collect();
    assert_eq!(ids, floor::PLACE_IDS);
    let evs = case.evidence();
    let vals = in_process_answers::<floor::Map>(&evs);
    check_tree_case(&case, &evs, &[vals]);
    eprintln!("demo_floor_trees: {} vectors (seed 1) agree", evs.len());
}

/// Every form of the demo floor and COLD maps (the 230-place one included) in one
/// temporary crate.
#[test]
fn cold_maps_match_tree_instance_and_interpreter() {
    let data = cold::data_dir(None);
    let all = std::env::var_os("GRAPHSPN_ALL_MAPS").is_some();
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
    // `FIXED`: the no-FPU targets' form (`SoftF32` rows, fixed-point messages), within
    // its bound.
    let every = [
        Variant::F32,
        Variant::F64,
        Variant::F32_SCALAR,
        Variant::F64_SCALAR,
        Variant::FIXED,
    ];
    let mut cases = vec![floor_case(every.to_vec(), 300)];
    for (i, path) in paths.iter().enumerate() {
        let map = cold::load_sequence(path).unwrap_or_else(|e| panic!("{e}"));
        let seed = 200 + i as u64;
        let trees = SpanningTrees::covering(&map, model.trees, seed).unwrap();
        // The largest map in every form, the others alternately scalar and SIMD f32.
        let variants = if map.num_places() >= 200 {
            every.to_vec()
        } else if i % 2 == 0 {
            vec![Variant::F32_SCALAR]
        } else {
            vec![Variant::F32]
        };
        let parts: Vec<String> = path
            .components()
            .rev()
            .take(2)
            .map(|c| c.as_os_str().to_string_lossy().to_lowercase())
            .collect();
        cases.push(TreeCase {
            name: format!("{}_{}", parts[1], parts[0]),
            model: model.clone(),
            map,
            trees,
            variants,
            vectors,
            seed,
            interpreter_every: 4,
            extreme_every: 0,
            factor_tables: true,
        });
    }
    harness::trees::tree_differential("tree_diff", &cases);
}
