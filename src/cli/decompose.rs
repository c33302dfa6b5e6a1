//! `graphspn decompose`: write the decompositions file that `compile --decompositions`,
//! `infer --decompositions-file` and `instance --decompositions-file` read.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::budget::{Budget, Work, read_map_within};
use super::flag_checks::{check_decomposition_count, parse_strategy};
use super::map_input::{data_dir, declare_map, map_fits};
use super::model_input::{decompositions_for, load_model};
use super::output::{Outputs, write_files};
use graphspn_compiler::decompose::DecompositionStrategy;

/// Arguments of `graphspn decompose`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn decompose --model generated/demo/model.json --map generated/demo/floor.json --out floor.decompositions.json
  graphspn decompose --model model.json --map Freiburg/seq1_cloudy1 --count 10 --seed 3 --out seq1.decompositions.json"
)]
pub struct DecomposeArgs {
    /// Model file (its templates are the components' shapes).
    #[arg(long)]
    model: PathBuf,
    /// The map: a JSON map, a COLD sequence folder, or a sequence name under --data.
    #[arg(long)]
    map: PathBuf,
    /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Number of decompositions kept (1..=1000), best of max(3 × count, 15) candidates.
    #[arg(long, default_value_t = 5)]
    count: usize,
    /// Seed of the decompositions.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// How decompositions are drawn: `paper` (the authors' scheme) or `cover` (frontier
    /// places join their neighbour's component rather than stay alone).
    #[arg(long, default_value = "paper", value_parser = parse_strategy)]
    strategy: DecompositionStrategy,
    /// Output decompositions file (JSON).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

/// Runs `graphspn decompose`.
pub fn run(args: DecomposeArgs) -> Result<()> {
    let mut outputs = Outputs::new(args.force);
    check_decomposition_count("--count", args.count)?;
    outputs.input_file("--model", &args.model)?;
    let map_path = declare_map(&args.map, data_dir(args.data), &mut outputs)?;
    outputs.file("--out", &args.out)?;
    let model = load_model(&args.model)?;
    let budget = Budget::new(
        format!("--count {}", args.count),
        Work::decompositions(args.count),
    );
    let loaded = read_map_within("--map", &map_path, &budget)?;
    map_fits(
        graphspn_compiler::inputs::check_map(&model, &loaded.map),
        &map_path,
        &args.model,
    )?;
    let decs = decompositions_for(
        &model,
        &loaded.map,
        None,
        args.count,
        args.seed,
        args.strategy,
    )?;
    let text = graphspn_compiler::decompose::file::to_json(&decs, &loaded.map, &model.templates)?;
    write_files(&[(&args.out, text.as_bytes())])?;
    eprintln!(
        "wrote {} decompositions of {} ({} places) to {}",
        decs.len(),
        loaded.map.name,
        loaded.map.num_places(),
        args.out.display()
    );
    Ok(())
}
