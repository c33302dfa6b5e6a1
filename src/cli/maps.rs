//! `graphspn stats`, `render` and `generate`: the map sub-commands.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use graphspn_compiler::family::AnyModel;
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::map::cold;
use graphspn_compiler::map::stats::{MapStats, comparison_table};
use graphspn_compiler::map::synthetic::{SyntheticParams, generate};
use graphspn_compiler::render::{RenderOptions, render_svg};
use graphspn_compiler::treemix::SpanningTrees;

use graphspn_compiler::domain;

use super::flag_checks::{check_trees_flag, flag_domain};
use super::map_input::{
    data_dir, declare_map, load_buildings, map_fits, read_map, require_data_dir,
};
use super::model_input::load_any_model;
use super::output::{Outputs, write_files, write_stdout};

fn synthetic(flag: &str, places: usize, seed: u64) -> Result<TopoMap> {
    flag_domain(flag, domain::synthetic_places("places", places))?;
    generate(&SyntheticParams::new(places, seed))
        .with_context(|| format!("generating a synthetic floor of {places} places (seed {seed})"))
}

/// Arguments of `graphspn stats`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn stats
  graphspn stats --synthetic 1000 --seed 4"
)]
pub struct StatsArgs {
    /// Folder of buildings, each a folder of COLD sequences: every building in it is
    /// counted (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps with
    /// Freiburg/, Saarbrucken/, Stockholm/).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Also generate a synthetic floor of this many places (10..=100000).
    #[arg(long)]
    synthetic: Option<usize>,
    /// Seed of the synthetic floor.
    #[arg(long, default_value_t = 0, requires = "synthetic")]
    seed: u64,
}

/// Runs `graphspn stats`.
pub fn stats(args: StatsArgs) -> Result<()> {
    let dir = require_data_dir(args.data)?;
    let syn = match args.synthetic {
        Some(n) => Some((n, synthetic("--synthetic", n, args.seed)?)),
        None => None,
    };
    let mut columns: Vec<(String, MapStats)> = Vec::new();
    let mut all = Vec::new();
    let mut per_building = Vec::new();
    let buildings = cold::buildings_in(&dir)?;
    if buildings.is_empty() {
        bail!(
            "--data {}: holds no building (folders of COLD sequences)",
            dir.display()
        );
    }
    for b in &buildings {
        let maps = load_buildings(&dir, std::slice::from_ref(b))?;
        per_building.push((b.clone(), MapStats::of_maps(&maps)));
        all.extend(maps);
    }
    let pooled = if buildings == cold::BUILDINGS {
        "COLD"
    } else {
        "all"
    };
    columns.push((pooled.into(), MapStats::of_maps(&all)));
    columns.extend(per_building);
    if let Some((n, m)) = &syn {
        columns.push((format!("synth {n}"), MapStats::of_map(m)));
    }
    let cols: Vec<(&str, &MapStats)> = columns.iter().map(|(n, s)| (n.as_str(), s)).collect();
    write_stdout(&comparison_table(&cols))
}

/// Arguments of `graphspn render`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    group = clap::ArgGroup::new("seeded").args(["synthetic", "model"]).multiple(true),
    after_help = "Examples:
  graphspn render --map Freiburg/seq1_cloudy1 --out freiburg.svg
  graphspn render --synthetic 500 --seed 2 --title \"A synthetic floor\" --out floor.svg
  graphspn render --map generated/demo/floor.json --model generated/demo/tree_model.json --tree 2 --out trees.svg"
)]
pub struct RenderArgs {
    /// A COLD sequence folder (nodes.dat + rooms.dat), a JSON map, or a
    /// sequence name such as Freiburg/seq1_cloudy1 under the data folder.
    #[arg(
        long,
        conflicts_with = "synthetic",
        required_unless_present = "synthetic"
    )]
    map: Option<PathBuf>,
    /// Draw a synthetic floor of this many places instead (10..=100000).
    #[arg(long)]
    synthetic: Option<usize>,
    /// Seed of the synthetic floor, or of the model's spanning trees.
    #[arg(long, default_value_t = 0, requires = "seeded")]
    seed: u64,
    /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Title (default: the map name).
    #[arg(long)]
    title: Option<String>,
    /// A tree-mixture model: draw one of its spanning trees of the map (`--tree`,
    /// seeded by `--seed`) over the map.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Which spanning tree to draw (1 = the first; at most the tree count).
    #[arg(long, requires = "model")]
    tree: Option<usize>,
    /// Spanning trees drawn for the map (1..=64; default: the model's), as `infer
    /// --trees` and `compile --count` mix them: the same seed and count draw the same
    /// trees.
    #[arg(long, requires = "model")]
    trees: Option<usize>,
    /// Output SVG file.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

/// Runs `graphspn render`.
pub fn render(args: RenderArgs) -> Result<()> {
    let mut outputs = Outputs::new(args.force);
    let map_path = match &args.map {
        Some(p) => Some(declare_map(p, data_dir(args.data), &mut outputs)?),
        None => None,
    };
    if let Some(p) = &args.model {
        outputs.input_file("--model", p)?;
    }
    outputs.file("--out", &args.out)?;
    let model = match &args.model {
        Some(p) => match load_any_model(p)? {
            AnyModel::TreeMixture(t) => {
                check_trees_flag(args.trees, false)?;
                Some(t)
            }
            AnyModel::Graphspn(_) => bail!(
                "--model {}: holds a GraphSPN; render draws the spanning trees of a tree mixture (infer --svg draws a GraphSPN's marginals)",
                p.display()
            ),
        },
        None => None,
    };
    let m = match (&map_path, args.synthetic) {
        (Some(p), _) => read_map(p)?.map,
        (None, Some(n)) => synthetic("--synthetic", n, args.seed)?,
        (None, None) => bail!("give --map PATH or --synthetic N"),
    };
    let tree = match &model {
        Some(t) => {
            if let (Some(map), Some(model)) = (&map_path, &args.model) {
                map_fits(graphspn_compiler::treemix::check_map(t, &m), map, model)?;
            }
            let count = args.trees.unwrap_or(t.trees);
            let k = args.tree.unwrap_or(1);
            if !(1..=count).contains(&k) {
                let whose = if args.trees.is_some() {
                    "--trees gives"
                } else {
                    "the model mixes"
                };
                bail!("--tree {k}: {whose} {count} trees (give 1 to {count})");
            }
            let trees = SpanningTrees::covering(&m, count, args.seed)?;
            Some((k, count, trees.forests[k - 1].edges()))
        }
        None => None,
    };
    let opts = RenderOptions {
        title: Some(args.title.unwrap_or_else(|| match &tree {
            Some((k, t, _)) => format!("{}: spanning tree {k} of {t} (seed {})", m.name, args.seed),
            None => format!(
                "{} ({} places, {} edges)",
                m.name,
                m.num_places(),
                m.num_edges()
            ),
        })),
        tree: tree.as_ref().map(|t| t.2.as_slice()),
        ..RenderOptions::default()
    };
    write_files(&[(&args.out, render_svg(&m, &opts).as_bytes())])?;
    eprintln!("wrote {} ({} places)", args.out.display(), m.num_places());
    Ok(())
}

/// Arguments of `graphspn generate`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn generate --places 1000 --out floor.json
  graphspn generate --places 100000 --seed 7 --out big.json --force"
)]
pub struct GenerateArgs {
    /// Number of places (10..=100000).
    #[arg(long)]
    places: usize,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output JSON file.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

/// Runs `graphspn generate`.
pub fn generate_cmd(args: GenerateArgs) -> Result<()> {
    let mut outputs = Outputs::new(args.force);
    outputs.file("--out", &args.out)?;
    let m = synthetic("--places", args.places, args.seed)?;
    write_files(&[(&args.out, m.to_json().as_bytes())])?;
    eprintln!(
        "wrote {}: {} places, {} edges",
        args.out.display(),
        m.num_places(),
        m.num_edges()
    );
    Ok(())
}
