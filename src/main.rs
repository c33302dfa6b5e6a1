//! The `graphspn` command-line tool.

use std::process::ExitCode;

mod cli;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// GraphSPN semantic maps: learn, infer, compile.
#[derive(Parser)]
#[command(
    name = "graphspn",
    version,
    about,
    after_help = "The 90 COLD maps ship in data/cold-topomaps and are read by default;\n--data DIR or $GRAPHSPN_DATA point elsewhere. File formats: docs/FORMATS.md.\n\nExample:\n  graphspn train --out model.json && graphspn infer --model model.json --map Freiburg/seq1_cloudy1"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the statistics of the COLD maps (per building and pooled), and of a
    /// synthetic map side by side when --synthetic is given.
    Stats(cli::maps::StatsArgs),
    /// Draw a map as SVG: places coloured by class, placeholders as dashed rings.
    Render(cli::maps::RenderArgs),
    /// Learn a model from annotated COLD maps: a GraphSPN (one template SPN per
    /// sub-graph template) or a tree mixture (--family tree-mixture).
    Train(cli::train::TrainArgs),
    /// Posterior class marginals (or the MPE labelling) of every place of a map
    /// given per-place evidence, exactly: through the instance GraphSPN or the tree
    /// mixture.
    Infer(cli::infer::InferArgs),
    /// Export the explicit instance SPN of a map (a GraphSPN's, or a tree mixture's
    /// with its trees) as JSON (every node) or Graphviz dot.
    Instance(cli::instance::InstanceArgs),
    /// Run the paper's experiments (classification, placeholders, novelty) and
    /// write REPORT.md, results.json and SVG figures.
    Reproduce(cli::reproduce::ReproduceArgs),
    /// Choose every model's settings (tree mixture, GraphSPN, tuned MRF-2/MRF-3) by
    /// leave-one-training-building-out validation; writes VALIDATION.md and validation.json.
    Validate(cli::reproduce::ValidateArgs),
    /// Run the paper's protocol (classification, placeholders, novelty) on your own
    /// maps against the validated baselines; writes REPORT.md, results.json, figures.
    Evaluate(cli::evaluate::EvaluateArgs),
    /// Compile the model (GraphSPN or tree mixture) of a known map into a no_std Rust
    /// source file.
    Compile(cli::compile::CompileArgs),
    /// Decompose a map into the model's templates and write the decompositions file
    /// `compile --decompositions` and `infer --decompositions-file` read.
    Decompose(cli::decompose::DecomposeArgs),
    /// Generate a synthetic office floor and save it as a JSON map.
    Generate(cli::maps::GenerateArgs),
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Stats(args) => cli::maps::stats(args),
        Command::Render(args) => cli::maps::render(args),
        Command::Train(args) => cli::train::run(args),
        Command::Infer(args) => cli::infer::run(args),
        Command::Instance(args) => cli::instance::run(args),
        Command::Reproduce(args) => cli::reproduce::run_cmd(args),
        Command::Validate(args) => cli::reproduce::validate_cmd(args),
        Command::Evaluate(args) => cli::evaluate::run_cmd(args),
        Command::Compile(args) => cli::compile::run(args),
        Command::Decompose(args) => cli::decompose::run(args),
        Command::Generate(args) => cli::maps::generate_cmd(args),
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line, each cause once (library errors already repeat their source).
            eprintln!("error: {}", cli::output::error_chain(&e));
            ExitCode::FAILURE
        }
    }
}
