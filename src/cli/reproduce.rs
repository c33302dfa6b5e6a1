//! `graphspn reproduce`: the paper's experiments, REPORT.md, results.json and figures.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;
use graphspn_compiler::decompose::DecompositionParams;
use graphspn_compiler::experiments::evidence::WrongClassDraw;
use graphspn_compiler::experiments::report::write_outputs;
use graphspn_compiler::experiments::reproduce::{ReproduceConfig, load_data, run};

use super::common::require_data_dir;

/// Arguments of `graphspn reproduce`.
#[derive(Args)]
pub struct ReproduceArgs {
    /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Output folder (REPORT.md, results.json, *.svg).
    #[arg(long)]
    out: PathBuf,
    /// Master seed of every random step.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Reduced run: Stockholm only, 2 maps, NL2 and NL5, 1 round.
    #[arg(long)]
    quick: bool,
    /// Draw the wrong evidence class among all 10 classes (the paper's effective
    /// noise, reproducing its Table 1) instead of the 9 wrong ones.
    #[arg(long)]
    paper_noise: bool,
    /// Decompositions per instance GraphSPN (default 5, the paper's).
    #[arg(long)]
    decompositions: Option<usize>,
    /// Candidate decompositions scored (default 15, or 3 × decompositions if larger).
    #[arg(long)]
    candidates: Option<usize>,
    /// Test buildings, comma-separated (default: all three).
    #[arg(long, value_delimiter = ',')]
    buildings: Option<Vec<String>>,
}

/// Runs `graphspn reproduce`.
pub fn run_cmd(args: ReproduceArgs) -> Result<()> {
    let data = require_data_dir(args.data)?;
    let mut cfg = if args.quick {
        ReproduceConfig::quick(args.seed)
    } else {
        ReproduceConfig::full(args.seed)
    };
    if args.paper_noise {
        cfg.wrong_draw = WrongClassDraw::AnyClass;
    }
    if let Some(d) = args.decompositions {
        let cands = args.candidates.unwrap_or((3 * d).max(15));
        cfg.decomposition = DecompositionParams {
            count: d,
            candidates: cands,
            seed: 0,
        };
    } else if let Some(c) = args.candidates {
        cfg.decomposition.candidates = c;
    }
    if let Some(b) = args.buildings {
        cfg.test_buildings = b;
    }
    let start = Instant::now();
    let all = load_data(&data)?;
    let (mut rep, setups) = run(&all, &cfg)?;
    rep.seconds = start.elapsed().as_secs_f64();
    write_outputs(&rep, &setups, &cfg, &args.out, "")?;
    eprintln!(
        "reproduction done in {:.1} s; wrote {}",
        start.elapsed().as_secs_f64(),
        args.out.join("REPORT.md").display()
    );
    Ok(())
}
