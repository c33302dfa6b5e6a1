//! `graphspn instance`: export the instance GraphSPN of a map as JSON or Graphviz dot.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};

use super::common::{data_dir, instance_for, load_map};

/// Output format of `graphspn instance`.
#[derive(Clone, Copy, ValueEnum)]
pub enum InstanceFormat {
    /// Every SPN node, the decompositions and the place ids.
    Json,
    /// A Graphviz digraph of the SPN.
    Dot,
}

/// Arguments of `graphspn instance`.
#[derive(Args)]
pub struct InstanceArgs {
    /// Model file written by `graphspn train`.
    #[arg(long)]
    model: PathBuf,
    /// The map: a JSON map, a COLD sequence folder, or a sequence name under --data.
    #[arg(long)]
    map: PathBuf,
    /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value = "json")]
    format: InstanceFormat,
    /// Number of decompositions mixed by the instance.
    #[arg(long, default_value_t = 5)]
    decompositions: usize,
    /// Seed of the decompositions.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `graphspn instance`.
pub fn run(args: InstanceArgs) -> Result<()> {
    let map = load_map(&args.map, data_dir(args.data))?;
    let (model, inst) = instance_for(&args.model, &map, args.decompositions, args.seed)?;
    let names: Vec<String> = model.templates.iter().map(|t| t.name.clone()).collect();
    let text = match args.format {
        InstanceFormat::Json => inst.to_json(&map, &names),
        InstanceFormat::Dot => inst.to_dot(&map),
    };
    match &args.out {
        Some(p) => {
            std::fs::write(p, &text).with_context(|| format!("writing {}", p.display()))?;
            eprintln!(
                "wrote the instance of {} ({} places, {} nodes, {} edges) to {}",
                map.name,
                map.num_places(),
                inst.spn.nodes.len(),
                inst.spn.num_edges(),
                p.display()
            );
        }
        None => super::common::write_stdout(&text)?,
    }
    Ok(())
}
