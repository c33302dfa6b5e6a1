//! `graphspn reproduce`: the paper's experiments, REPORT.md, results.json and figures.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use graphspn_compiler::decompose::DecompositionParams;
use graphspn_compiler::experiments::evidence::{NoiseLevel, WrongClassDraw};
use graphspn_compiler::experiments::report::{validation_markdown, write_outputs};
use graphspn_compiler::experiments::reproduce::{ReproduceConfig, load_data, run};
use graphspn_compiler::experiments::validate::{ModelSettings, ValidationGrid, validate_for};
use graphspn_compiler::learn::TrainingSettings;
use graphspn_compiler::mrf::Normalisation;
use std::collections::BTreeMap;

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
    /// Test buildings, comma-separated (default: all three, minus --exclude).
    #[arg(long, value_delimiter = ',')]
    buildings: Option<Vec<String>>,
    /// Leave this building out entirely (validation on training buildings only:
    /// each remaining building is tested with a model trained on the other).
    #[arg(long)]
    exclude: Option<String>,
    /// Noise levels to run, comma-separated (default: 1..6).
    #[arg(long, value_delimiter = ',')]
    levels: Option<Vec<u8>>,
    /// Test maps per building.
    #[arg(long)]
    maps: Option<usize>,
    /// Evidence rounds per map and level.
    #[arg(long)]
    rounds: Option<usize>,
    /// Skip the novelty-detection experiment.
    #[arg(long)]
    no_novelty: bool,
    /// Use the settings of a saved validation (`graphspn validate --out DIR` writes
    /// DIR/validation.json) instead of running the validation again.
    #[arg(long)]
    settings: Option<PathBuf>,
    /// Tiny validation grid (smoke runs).
    #[arg(long)]
    tiny_grid: bool,
    /// Training settings as JSON merged over the defaults, e.g. '{"em":"soft"}'.
    #[arg(long)]
    training: Option<String>,
    /// Paper-style MRF potentials from PMI ratios instead of joint frequencies.
    #[arg(long)]
    mrf_pmi: bool,
}

/// Arguments of `graphspn validate`.
#[derive(Args)]
pub struct ValidateArgs {
    /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Output folder (VALIDATION.md, validation.json).
    #[arg(long)]
    out: PathBuf,
    /// Master seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Test buildings to validate for, comma-separated (default: all three).
    #[arg(long, value_delimiter = ',')]
    buildings: Option<Vec<String>>,
    /// Tiny grid (smoke runs).
    #[arg(long)]
    tiny_grid: bool,
}

/// Runs `graphspn validate`: the leave-one-training-building-out search of every
/// model's settings, per test building; writes validation.json and VALIDATION.md.
pub fn validate_cmd(args: ValidateArgs) -> Result<()> {
    let data = require_data_dir(args.data)?;
    let start = Instant::now();
    let mut cfg = ReproduceConfig::full(args.seed);
    if args.tiny_grid {
        cfg.grid = ValidationGrid::tiny();
    }
    let all = load_data(&data)?;
    let buildings = args.buildings.unwrap_or(cfg.test_buildings.clone());
    let mut vals = Vec::new();
    for b in &buildings {
        if !all.contains_key(b) {
            anyhow::bail!("--buildings {b}: no such building");
        }
        eprintln!("validating the settings for test building {b} (on the other two buildings)");
        vals.push(validate_for(&all, b, &cfg)?);
    }
    let settings: BTreeMap<String, ModelSettings> = vals
        .iter()
        .map(|v| (v.test_building.clone(), v.chosen.clone()))
        .collect();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let json = serde_json::json!({ "settings": settings, "validation": vals });
    let p = args.out.join("validation.json");
    std::fs::write(&p, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("writing {}", p.display()))?;
    let md = validation_markdown(&vals, start.elapsed().as_secs_f64());
    let p = args.out.join("VALIDATION.md");
    std::fs::write(&p, md).with_context(|| format!("writing {}", p.display()))?;
    eprintln!(
        "validation done in {:.1} s; wrote {}",
        start.elapsed().as_secs_f64(),
        p.display()
    );
    Ok(())
}

/// Reads the per-building settings of a validation.json.
fn read_settings(path: &std::path::Path) -> Result<BTreeMap<String, ModelSettings>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    let s = v
        .get("settings")
        .with_context(|| format!("{}: no \"settings\" object", path.display()))?;
    serde_json::from_value(s.clone())
        .with_context(|| format!("{}: bad \"settings\"", path.display()))
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
    let start = Instant::now();
    let mut all = load_data(&data)?;
    if let Some(x) = &args.exclude {
        if all.remove(x).is_none() {
            anyhow::bail!("--exclude {x}: no such building");
        }
        cfg.test_buildings.retain(|b| b != x);
    }
    if let Some(b) = args.buildings {
        cfg.test_buildings = b;
    }
    if let Some(l) = args.levels {
        cfg.levels = l
            .into_iter()
            .map(NoiseLevel::new)
            .collect::<Result<_, _>>()?;
    }
    if let Some(m) = args.maps {
        cfg.maps_per_building = m;
    }
    if let Some(r) = args.rounds {
        cfg.rounds = r;
    }
    if args.no_novelty {
        cfg.novelty = false;
    }
    if args.tiny_grid {
        cfg.grid = ValidationGrid::tiny();
    }
    if let Some(p) = &args.settings {
        cfg.settings = Some(read_settings(p)?);
    }
    if let Some(t) = &args.training {
        let mut v = cfg.training.to_value();
        let patch: serde_json::Value = serde_json::from_str(t).context("--training JSON")?;
        if let (Some(obj), Some(p)) = (v.as_object_mut(), patch.as_object()) {
            for (k, x) in p {
                obj.insert(k.clone(), x.clone());
            }
        }
        cfg.training = TrainingSettings::from_value(&v).context("--training settings")?;
    }
    if args.mrf_pmi {
        cfg.cooccurrence.normalisation = Normalisation::Pmi;
    }
    let (mut rep, setups) = run(&all, &cfg)?;
    rep.seconds = start.elapsed().as_secs_f64();
    let check =
        super::generated_check::section(args.seed, if args.quick { 1 } else { cfg.rounds })?;
    write_outputs(&rep, &setups, &cfg, &args.out, &check)?;
    eprintln!(
        "reproduction done in {:.1} s; wrote {}",
        start.elapsed().as_secs_f64(),
        args.out.join("REPORT.md").display()
    );
    Ok(())
}
