//! `graphspn train`: learn a model from annotated COLD maps.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use graphspn_compiler::learn::{Progress, TrainingSettings, train_model};
use graphspn_compiler::template::Template;

use super::common::{load_buildings, require_data_dir};

/// Arguments of `graphspn train`.
#[derive(Args)]
pub struct TrainArgs {
    /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Buildings to train on, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "Freiburg,Saarbrucken")]
    buildings: Vec<String>,
    /// Output model file (JSON).
    #[arg(long)]
    out: PathBuf,
    /// Master seed of every random step.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// EM epochs.
    #[arg(long)]
    epochs: Option<usize>,
    /// Decompositions of each training map per template.
    #[arg(long)]
    decompositions_per_map: Option<usize>,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

/// Runs `graphspn train`.
pub fn run(args: TrainArgs) -> Result<()> {
    if args.out.exists() && !args.force {
        anyhow::bail!("{} exists: pass --force to replace it", args.out.display());
    }
    let data = require_data_dir(args.data)?;
    let maps = load_buildings(&data, &args.buildings)?;
    let mut settings = TrainingSettings {
        seed: args.seed,
        ..TrainingSettings::default()
    };
    if let Some(e) = args.epochs {
        settings.epochs = e;
    }
    if let Some(d) = args.decompositions_per_map {
        settings.decompositions_per_map = d;
    }
    let start = Instant::now();
    let (model, trainings) = train_model(&maps, &Template::paper_set(), &settings, Progress::Auto)?;
    let elapsed = start.elapsed();
    for t in &trainings {
        match &t.report {
            Some(r) => eprintln!(
                "{:>9}: {:>6} samples ({} distinct after augmentation), log-likelihood per sample {:.4} -> {:.4}",
                t.template,
                t.samples,
                r.num_distinct,
                r.initial_log_likelihood,
                r.log_likelihood_per_epoch
                    .last()
                    .copied()
                    .unwrap_or(f64::NAN)
            ),
            None => eprintln!("{:>9}: uniform", t.template),
        }
    }
    model
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    eprintln!(
        "trained on {} maps in {:.2} s; wrote {}",
        maps.len(),
        elapsed.as_secs_f64(),
        args.out.display()
    );
    Ok(())
}
