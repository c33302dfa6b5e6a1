//! The reproduction report's check of the generated code: for the fixed map compiled
//! into `graphspn-generated` (the largest COLD map, Saarbrücken `seq2_night1`, with the
//! demo model), the generated `marginals` must agree with the interpreter evaluating
//! the same instance GraphSPN on evidence simulated by the experiment's protocol.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::{Context, Result};
use graphspn_compiler::decompose::{DecompositionParams, decompose_best};
use graphspn_compiler::experiments::evidence::{NoiseLevel, simulate_map_evidence};
use graphspn_compiler::experiments::validation_report::counted;
use graphspn_compiler::instance::Instance;
use graphspn_compiler::interpreter::{Evaluator, Evidence};
use graphspn_compiler::learn::Model;
use graphspn_compiler::map::TopoMap;
use graphspn_generated::saarbrucken_seq2_night1 as compiled;

/// The inputs `generated/build.rs` compiled, embedded so the check needs no files.
const MODEL_JSON: &str = include_str!("../../generated/demo/model.json");
const MAP_JSON: &str = include_str!("../../generated/demo/saarbrucken_seq2_night1.json");

/// Runs the check on `rounds` evidence draws per noise level (with and without
/// placeholder evidence) and returns a Markdown section for the report.
pub fn section(seed: u64, rounds: usize) -> Result<String> {
    let model = Model::from_json(MODEL_JSON).context("embedded demo model")?;
    let map = TopoMap::from_json(MAP_JSON).context("embedded Saarbrucken map")?;
    // The same decompositions as generated/build.rs (Builder: seed 0, best 5 of 15).
    let decs = decompose_best(
        &map,
        &model.templates,
        &DecompositionParams {
            count: 5,
            candidates: 15,
            seed: 0,
            ..DecompositionParams::default()
        },
    )?;
    let instance = Instance::build(&model, &map, decs)?;
    let mut eval = Evaluator::new(&instance.spn)?;
    let n = map.num_places();
    anyhow::ensure!(
        n == compiled::NUM_PLACES,
        "compiled map has {} places, the embedded one {n}",
        compiled::NUM_PLACES
    );
    let fixed: Vec<Option<u32>> = vec![None; n];
    let (mut max_abs, mut max_rel, mut agree, mut total, mut cases) =
        (0f64, 0f64, 0usize, 0usize, 0usize);
    let (mut t_gen, mut t_int) = (0f64, 0f64);
    let mut ev = [[0f32; compiled::NUM_CLASSES]; compiled::NUM_PLACES];
    let mut out = [[0f32; compiled::NUM_CLASSES]; compiled::NUM_PLACES];
    for level in NoiseLevel::all() {
        for placeholders in [false, true] {
            for r in 0..rounds {
                let s = seed
                    ^ (0x6e6e_0000
                        + u64::from(level.get()) * 1000
                        + r as u64 * 2
                        + placeholders as u64);
                let sim = simulate_map_evidence(&map, level, placeholders, s)?;
                for (row, src) in ev.iter_mut().zip(&sim.rows) {
                    for (x, &y) in row.iter_mut().zip(src) {
                        *x = y as f32;
                    }
                }
                // The interpreter gets exactly the f32 values the generated code sees.
                let rows: Vec<Vec<f64>> = ev
                    .iter()
                    .map(|r| r.iter().map(|&x| f64::from(x)).collect())
                    .collect();
                let t = Instant::now();
                let m = eval.marginals(&fixed, &Evidence::from_rows(rows))?;
                t_int += t.elapsed().as_secs_f64();
                let t = Instant::now();
                let ll = compiled::marginals(&ev, &mut out)
                    .map_err(|e| anyhow::anyhow!("generated marginals: {e}"))?;
                t_gen += t.elapsed().as_secs_f64();
                max_rel = max_rel.max(
                    ((f64::from(ll) - m.log_likelihood) / m.log_likelihood.abs().max(1.0)).abs(),
                );
                for (g, i) in out.iter().zip(&m.probs) {
                    for (a, b) in g.iter().zip(i) {
                        max_abs = max_abs.max((f64::from(*a) - b).abs());
                    }
                    let ag = argmax(g.iter().map(|&x| f64::from(x)));
                    let ai = argmax(i.iter().copied());
                    agree += usize::from(ag == ai);
                    total += 1;
                }
                cases += 1;
            }
        }
    }
    let ok = max_abs <= 1e-4 && max_rel <= 1e-4;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Fixed map: `{}` ({} places), compiled into `graphspn-generated` with the demo model \
         (`generated/demo/model.json`, trained on all 90 maps, so this check is about agreement, \
         not accuracy). {cases} evidence vectors (NL1–6 × {}, with and without \
         placeholder evidence): max |Δ marginal| = {max_abs:.2e}, max relative Δ log-likelihood = \
         {max_rel:.2e} (tolerance 1e-4, f32), argmax agreement {agree}/{total} places. \
         **{}**. Time per `marginals` call: generated {:.1} µs, interpreter {:.1} µs ({:.0}×).",
        map.name,
        n,
        counted(rounds, "round"),
        if ok { "Agrees" } else { "DISAGREES" },
        t_gen / cases as f64 * 1e6,
        t_int / cases as f64 * 1e6,
        t_int / t_gen.max(1e-12)
    );
    anyhow::ensure!(ok, "generated code disagrees with the interpreter: {s}");
    Ok(s)
}

fn argmax(it: impl Iterator<Item = f64>) -> usize {
    let mut best = (0, f64::NEG_INFINITY);
    for (i, x) in it.enumerate() {
        if x > best.1 {
            best = (i, x);
        }
    }
    best.0
}
