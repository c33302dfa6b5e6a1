//! `graphspn train`: learn a model from annotated COLD maps.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use graphspn_compiler::learn::{Progress, TrainingSettings, train_model};
use graphspn_compiler::template::Template;

use super::common::{check_buildings, load_buildings, require_data_dir};
use super::output::{Outputs, write_files};

/// Arguments of `graphspn train`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn train --out model.json
  graphspn train --buildings Freiburg,Saarbrucken,Stockholm --epochs 20 --seed 3 --out model.json --force"
)]
pub struct TrainArgs {
    /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Buildings to train on, comma-separated, each at most once.
    #[arg(long, value_delimiter = ',', default_value = "Freiburg,Saarbrucken")]
    buildings: Vec<String>,
    /// Output model file (JSON).
    #[arg(long)]
    out: PathBuf,
    /// Master seed of every random step.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// EM epochs (at least 1).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    epochs: Option<u32>,
    /// Decompositions of each training map per template (at least 1).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    decompositions_per_map: Option<u32>,
    /// Template temperature: every sum weight raised to this power and renormalised
    /// after training (< 1 flattens the learned statistics; default 1, none).
    #[arg(long)]
    temperature: Option<f64>,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

/// Runs `graphspn train`.
pub fn run(args: TrainArgs) -> Result<()> {
    check_buildings("--buildings", &args.buildings)?;
    let data = require_data_dir(args.data)?;
    let mut outputs = Outputs::new(args.force);
    outputs.input("--data", &data);
    outputs.file("--out", &args.out)?;
    let maps = load_buildings(&data, &args.buildings)?;
    let mut settings = TrainingSettings {
        seed: args.seed,
        ..TrainingSettings::default()
    };
    if let Some(e) = args.epochs {
        settings.epochs = e as usize;
    }
    if let Some(d) = args.decompositions_per_map {
        settings.decompositions_per_map = d as usize;
    }
    if let Some(t) = args.temperature {
        graphspn_compiler::learn::check_temperature(t).context("--temperature")?;
        settings.temperature = t;
    }
    let start = Instant::now();
    let (model, trainings) = train_model(&maps, &Template::paper_set(), &settings, Progress::Auto)?;
    let elapsed = start.elapsed();
    for t in &trainings {
        match &t.report {
            Some(r) => match r.log_likelihood_per_epoch.last() {
                Some(last) => eprintln!(
                    "{:>9}: {:>6} samples ({} distinct after augmentation), log-likelihood per sample {:.4} -> {:.4}",
                    t.template, t.samples, r.num_distinct, r.initial_log_likelihood, last
                ),
                None => eprintln!(
                    "{:>9}: {:>6} samples ({} distinct after augmentation), log-likelihood per sample {:.4} (no epoch run)",
                    t.template, t.samples, r.num_distinct, r.initial_log_likelihood
                ),
            },
            None => eprintln!("{:>9}: uniform", t.template),
        }
    }
    let text = model.to_json()?;
    write_files(&[(&args.out, text.as_bytes())])?;
    eprintln!(
        "trained on {} maps in {:.2} s; wrote {}",
        maps.len(),
        elapsed.as_secs_f64(),
        args.out.display()
    );
    Ok(())
}
