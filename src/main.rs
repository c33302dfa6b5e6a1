//! The `graphspn` command-line tool.

use std::path::PathBuf;

mod cli;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use graphspn_compiler::map::stats::{MapStats, comparison_table};
use graphspn_compiler::map::synthetic::{SyntheticParams, generate};
use graphspn_compiler::map::{TopoMap, cold};
use graphspn_compiler::render::{RenderOptions, render_svg};

/// GraphSPN semantic maps: learn, infer, compile.
#[derive(Parser)]
#[command(name = "graphspn", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the statistics of the COLD maps (per building and pooled), and of a
    /// synthetic map side by side when --synthetic is given.
    Stats {
        /// Folder holding Freiburg/, Saarbrucken/, Stockholm/ (default: $GRAPHSPN_DATA).
        #[arg(long)]
        data: Option<PathBuf>,
        /// Also generate a synthetic floor of this many places.
        #[arg(long)]
        synthetic: Option<usize>,
        /// Seed of the synthetic floor.
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
    /// Draw a map as SVG: places coloured by class, placeholders as dashed rings.
    Render {
        /// A COLD sequence folder (nodes.dat + rooms.dat), a JSON map, or a
        /// sequence name such as Freiburg/seq1_cloudy1 under the data folder.
        #[arg(long, conflicts_with = "synthetic")]
        map: Option<PathBuf>,
        /// Draw a synthetic floor of this many places instead.
        #[arg(long)]
        synthetic: Option<usize>,
        /// Seed of the synthetic floor.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA).
        #[arg(long)]
        data: Option<PathBuf>,
        /// Title (default: the map name).
        #[arg(long)]
        title: Option<String>,
        /// Output SVG file.
        #[arg(long)]
        out: PathBuf,
    },
    /// Learn a model (one template SPN per sub-graph template) from annotated COLD maps.
    Train(cli::train::TrainArgs),
    /// Posterior class marginals (or the MPE labelling) of every place of a map
    /// given per-place evidence, through the instance GraphSPN.
    Infer(cli::infer::InferArgs),
    /// Export the instance GraphSPN of a map as JSON (every node) or Graphviz dot.
    Instance(cli::instance::InstanceArgs),
    /// Run the paper's experiments (classification, placeholders, novelty) and
    /// write REPORT.md, results.json and SVG figures.
    Reproduce(cli::reproduce::ReproduceArgs),
    /// Choose every model's settings (GraphSPN, tuned MRF-2/MRF-3) by
    /// leave-one-training-building-out validation; writes VALIDATION.md and validation.json.
    Validate(cli::reproduce::ValidateArgs),
    /// Compile the GraphSPN of a known map into a no_std Rust source file.
    Compile(cli::compile::CompileArgs),
    /// Generate a synthetic office floor and save it as a JSON map.
    Generate {
        /// Number of places (10..=100000).
        #[arg(long)]
        places: usize,
        /// Seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output JSON file.
        #[arg(long)]
        out: PathBuf,
    },
}

fn data_dir(arg: Option<PathBuf>) -> Option<PathBuf> {
    arg.or_else(|| std::env::var_os("GRAPHSPN_DATA").map(PathBuf::from))
}

fn synthetic(places: usize, seed: u64) -> Result<TopoMap> {
    generate(&SyntheticParams::new(places, seed))
        .with_context(|| format!("generating a synthetic floor of {places} places (seed {seed})"))
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Stats {
            data,
            synthetic: syn,
            seed,
        } => {
            let mut columns: Vec<(String, MapStats)> = Vec::new();
            match data_dir(data) {
                Some(dir) => {
                    let mut all = Vec::new();
                    let mut per_building = Vec::new();
                    for b in cold::BUILDINGS {
                        let maps = cold::load_building(&dir, b)
                            .with_context(|| format!("loading {b} from {}", dir.display()))?;
                        per_building.push((b.to_string(), MapStats::of_maps(&maps)));
                        all.extend(maps);
                    }
                    columns.push(("COLD".into(), MapStats::of_maps(&all)));
                    columns.extend(per_building);
                }
                None if syn.is_some() => {
                    eprintln!(
                        "no data folder (--data or $GRAPHSPN_DATA): comparing with the built-in COLD reference statistics"
                    );
                    columns.push(("COLD (ref)".into(), MapStats::cold_reference()));
                }
                None => bail!("no data folder: pass --data DIR or set GRAPHSPN_DATA"),
            }
            if let Some(n) = syn {
                let m = synthetic(n, seed)?;
                columns.push((format!("synth {n}"), MapStats::of_map(&m)));
            }
            let cols: Vec<(&str, &MapStats)> =
                columns.iter().map(|(n, s)| (n.as_str(), s)).collect();
            print!("{}", comparison_table(&cols));
        }
        Command::Render {
            map,
            synthetic: syn,
            seed,
            data,
            title,
            out,
        } => {
            let m = match (map, syn) {
                (Some(p), _) => cli::common::load_map(&p, data_dir(data))?,
                (None, Some(n)) => synthetic(n, seed)?,
                (None, None) => bail!("give --map PATH or --synthetic N"),
            };
            let opts = RenderOptions {
                title: Some(title.unwrap_or_else(|| {
                    format!(
                        "{} ({} places, {} edges)",
                        m.name,
                        m.num_places(),
                        m.num_edges()
                    )
                })),
                ..RenderOptions::default()
            };
            std::fs::write(&out, render_svg(&m, &opts))
                .with_context(|| format!("writing {}", out.display()))?;
            eprintln!("wrote {} ({} places)", out.display(), m.num_places());
        }
        Command::Train(args) => cli::train::run(args)?,
        Command::Infer(args) => cli::infer::run(args)?,
        Command::Instance(args) => cli::instance::run(args)?,
        Command::Reproduce(args) => cli::reproduce::run_cmd(args)?,
        Command::Validate(args) => cli::reproduce::validate_cmd(args)?,
        Command::Compile(args) => cli::compile::run(args)?,
        Command::Generate { places, seed, out } => {
            let m = synthetic(places, seed)?;
            m.save(&out)?;
            eprintln!(
                "wrote {}: {} places, {} edges",
                out.display(),
                m.num_places(),
                m.num_edges()
            );
        }
    }
    Ok(())
}
