//! A first accuracy figure: train on two COLD buildings, then for 5 maps of the third
//! simulate noisy evidence at each paper noise level (seeded) and compare the accuracy
//! of the argmax of the tree mixture's and of the instance GraphSPN's marginals (the
//! paper's settings for both: no validation here, see `graphspn reproduce` for that)
//! with the argmax of the evidence alone.
//!
//! `cargo run --release --example accuracy [-- TEST_BUILDING [SEED]]` (reads the
//! shipped COLD maps, or `$GRAPHSPN_DATA` when set)
//! (default test building Stockholm, seed 0).

use std::time::Instant;

use anyhow::{Context, Result, bail};
use graphspn_compiler::experiments::evidence::{NoiseLevel, map_truth, simulate_map_evidence};
use graphspn_compiler::instance::{Instance, InstanceModel, InstanceParams};
use graphspn_compiler::interpreter::Evidence;
use graphspn_compiler::learn::{Progress, TrainingSettings, train_model};
use graphspn_compiler::map::cold;
use graphspn_compiler::template::Template;
use graphspn_compiler::treemix::{TreeInstance, TreeTraining, train_tree_mixture};

fn argmax(row: &[f64]) -> usize {
    let mut best = 0;
    for (k, &p) in row.iter().enumerate() {
        if p > row[best] {
            best = k;
        }
    }
    best
}

fn main() -> Result<()> {
    let data = graphspn::map::cold::data_dir(None);
    let mut args = std::env::args().skip(1);
    let test_building = args.next().unwrap_or_else(|| "Stockholm".into());
    let seed: u64 = match args.next() {
        Some(s) => s.parse().with_context(|| format!("seed {s:?}"))?,
        None => 0,
    };
    if !cold::BUILDINGS.contains(&test_building.as_str()) {
        bail!("unknown building {test_building:?}");
    }
    let mut train = Vec::new();
    for b in cold::BUILDINGS.iter().filter(|&&b| b != test_building) {
        train.extend(cold::load_building(&data, b).with_context(|| format!("loading {b}"))?);
    }
    let start = Instant::now();
    let settings = TrainingSettings {
        seed,
        ..TrainingSettings::default()
    };
    let (model, _) = train_model(&train, &Template::paper_set(), &settings, Progress::Hidden)?;
    // The settings validation chose for test building Stockholm.
    let mut tt = TreeTraining {
        evidence_exponent: 3,
        ..TreeTraining::default()
    };
    tt.potentials.coupling = 1.0;
    let trees = train_tree_mixture(&train, &tt)?;
    println!(
        "trained on {} maps in {:.2} s; testing on 5 {test_building} maps (seed {seed})",
        train.len(),
        start.elapsed().as_secs_f64()
    );
    let test: Vec<_> = cold::load_building(&data, &test_building)?
        .into_iter()
        .take(5)
        .collect();
    let mut instances = Vec::new();
    for (i, map) in test.iter().enumerate() {
        let params = InstanceParams {
            seed: seed.wrapping_add(i as u64),
            ..InstanceParams::default()
        };
        let inst = Instance::for_map(&model, map, &params)?;
        println!(
            "  {}: {} places, instance {} nodes / {} edges",
            map.name,
            map.num_places(),
            inst.spn.nodes.len(),
            inst.spn.num_edges()
        );
        instances.push((
            InstanceModel::new(inst)?,
            TreeInstance::with_covering_trees(&trees, map, seed.wrapping_add(i as u64))?,
        ));
    }
    println!("level  trees%  graphspn%  evidence%   per map (trees/graphspn/evidence)");
    for level in NoiseLevel::all() {
        let mut per_map = Vec::new();
        for (i, (map, (im, ti))) in test.iter().zip(&mut instances).enumerate() {
            let truth = map_truth(map)?;
            let ev = simulate_map_evidence(
                map,
                level,
                false,
                seed ^ (i as u64 * 7919 + level.get() as u64),
            )?;
            let m = im.marginals(&Evidence::from_rows(ev.rows.clone()))?;
            ti.set_all_evidence(&ev.rows)?;
            let t = ti.marginals()?.mixed;
            let n = truth.len() as f64;
            let hits = |rows: &[Vec<f64>]| {
                rows.iter()
                    .zip(&truth)
                    .filter(|(r, t)| argmax(r) == **t as usize)
                    .count() as f64
                    / n
            };
            per_map.push((hits(&t.probs), hits(&m.probs), hits(&ev.rows)));
        }
        let k = per_map.len() as f64;
        let t = per_map.iter().map(|x| x.0).sum::<f64>() / k * 100.0;
        let g = per_map.iter().map(|x| x.1).sum::<f64>() / k * 100.0;
        let e = per_map.iter().map(|x| x.2).sum::<f64>() / k * 100.0;
        let detail: Vec<String> = per_map
            .iter()
            .map(|(a, b, c)| format!("{:.1}/{:.1}/{:.1}", a * 100.0, b * 100.0, c * 100.0))
            .collect();
        println!(
            "NL{}    {t:6.1}  {g:8.1}  {e:9.1}   {}",
            level.get(),
            detail.join("  ")
        );
    }
    Ok(())
}
