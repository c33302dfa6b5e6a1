//! `graphspn instance`: export the instance SPN of a map (the GraphSPN's, or the
//! explicit SPN of a tree mixture) as JSON or Graphviz dot.

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, ValueEnum};

use super::budget::{Budget, Work, read_map_within};
use super::flag_checks::{
    check_decomposition_count, check_trees_flag, parse_strategy, refuse_graphspn_flags,
};
use super::map_input::{data_dir, declare_map, map_fits};
use super::model_input::{
    count_decompositions_file, decompositions_for, instance_of, load_any_model,
};
use super::output::{Outputs, emit};

use graphspn_compiler::decompose::DecompositionStrategy;
use graphspn_compiler::family::AnyModel;
use graphspn_compiler::instance::{spn_dot, tree_instance_json};
use graphspn_compiler::treemix::{TreeInstance, instance_spn};

/// Output format of `graphspn instance`.
#[derive(Clone, Copy, ValueEnum)]
pub enum InstanceFormat {
    /// Every SPN node, the decompositions (a tree mixture: its spanning trees) and the
    /// place ids.
    Json,
    /// A Graphviz digraph of the SPN.
    Dot,
}

/// Arguments of `graphspn instance`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn instance --model generated/demo/model.json --map generated/demo/floor.json --out floor-instance.json
  graphspn instance --model model.json --map Freiburg/seq1_cloudy1 --format dot --decompositions 1 | dot -Tsvg > spn.svg
  graphspn instance --model generated/demo/tree_model.json --map generated/demo/floor.json --out trees-instance.json"
)]
pub struct InstanceArgs {
    /// Model file written by `graphspn train` (a GraphSPN, or a tree mixture: its
    /// explicit SPN, each tree in its directed form, and the trees are exported).
    #[arg(long)]
    model: PathBuf,
    /// The map: a JSON map, a COLD sequence folder, or a sequence name under --data.
    #[arg(long)]
    map: PathBuf,
    /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value = "json")]
    format: InstanceFormat,
    /// GraphSPN: number of decompositions mixed by the instance (1..=1000; default 5).
    #[arg(long)]
    decompositions: Option<usize>,
    /// Read the decompositions from this file (written by `graphspn decompose`).
    #[arg(long, conflicts_with_all = ["decompositions", "seed"])]
    decompositions_file: Option<PathBuf>,
    /// Seed of the decompositions, or of a tree mixture's spanning trees.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Tree mixture: spanning trees mixed (1..=64; default: the model's), as `infer
    /// --trees` and `compile --count` mix them.
    #[arg(long)]
    trees: Option<usize>,
    /// GraphSPN: how decompositions are drawn: `paper` (the authors' scheme, the
    /// default) or `cover` (frontier places join their neighbour's component rather
    /// than stay alone).
    #[arg(long, value_parser = parse_strategy, conflicts_with = "decompositions_file")]
    strategy: Option<DecompositionStrategy>,
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Replace an existing --out file.
    #[arg(long)]
    force: bool,
}

/// Runs `graphspn instance`.
pub fn run(args: InstanceArgs) -> Result<()> {
    let mut outputs = Outputs::new(args.force);
    outputs.input_file("--model", &args.model)?;
    let map_path = declare_map(&args.map, data_dir(args.data), &mut outputs)?;
    if let Some(f) = &args.decompositions_file {
        // Checked by `count_decompositions_file` once the model is known to be a GraphSPN.
        outputs.input("--decompositions-file", f);
    }
    if let Some(p) = &args.out {
        outputs.file("--out", p)?;
    }
    let model = match load_any_model(&args.model)? {
        AnyModel::Graphspn(m) => {
            check_trees_flag(args.trees, true)?;
            m
        }
        AnyModel::TreeMixture(mut t) => {
            refuse_graphspn_flags(&[
                ("--decompositions", args.decompositions.is_some()),
                ("--decompositions-file", args.decompositions_file.is_some()),
                ("--strategy", args.strategy.is_some()),
            ])?;
            check_trees_flag(args.trees, false)?;
            t.trees = args.trees.unwrap_or(t.trees);
            let budget = Budget::new(
                format!("the explicit SPN of {} trees", t.trees),
                Work::TreeSpn {
                    trees: t.trees,
                    classes: t.classes.len(),
                },
            )
            .advice(
                "use a smaller map (`graphspn infer` answers queries without the explicit SPN)",
            );
            let loaded = read_map_within("--map", &map_path, &budget)?;
            let map = &loaded.map;
            map_fits(
                graphspn_compiler::treemix::check_map(&t, map),
                &map_path,
                &args.model,
            )?;
            let inst = TreeInstance::with_covering_trees(&t, map, args.seed)?;
            let spn = instance_spn(&inst)?;
            let text = match args.format {
                InstanceFormat::Json => tree_instance_json(map, inst.trees(), &spn),
                InstanceFormat::Dot => spn_dot(map, &spn, &format!("tree mixture of {}", map.name)),
            };
            emit(args.out.as_deref(), &text)?;
            if let Some(p) = &args.out {
                eprintln!(
                    "wrote the tree-mixture instance of {} ({} trees, {} nodes, {} edges) to {}",
                    map.name,
                    inst.trees().len(),
                    spn.nodes.len(),
                    spn.num_edges(),
                    p.display()
                );
            }
            return Ok(());
        }
    };
    // The decompositions step; the explicit SPN of the decompositions made is
    // estimated exactly before it is built ([`instance_of`]).
    let count = args.decompositions.unwrap_or(5);
    check_decomposition_count("--decompositions", count)?;
    let budget = match &args.decompositions_file {
        Some(f) => {
            let count = count_decompositions_file("--decompositions-file", f)?;
            Budget::new(
                format!(
                    "--decompositions-file {} ({count} decompositions)",
                    f.display()
                ),
                Work::Decompositions {
                    count,
                    candidates: 0,
                },
            )
        }
        None => Budget::new(
            format!("--decompositions {count}"),
            Work::decompositions(count),
        ),
    };
    let loaded = read_map_within("--map", &map_path, &budget)?;
    let map = &loaded.map;
    map_fits(
        graphspn_compiler::inputs::check_map(&model, map),
        &map_path,
        &args.model,
    )?;
    let decs = decompositions_for(
        &model,
        map,
        args.decompositions_file.as_deref(),
        count,
        args.seed,
        args.strategy.unwrap_or(DecompositionStrategy::Paper),
    )?;
    let inst = instance_of(&model, map, decs)?;
    let names: Vec<String> = model.templates.iter().map(|t| t.name.clone()).collect();
    let text = match args.format {
        InstanceFormat::Json => inst.to_json(map, &names),
        InstanceFormat::Dot => inst.to_dot(map),
    };
    emit(args.out.as_deref(), &text)?;
    if let Some(p) = &args.out {
        eprintln!(
            "wrote the instance of {} ({} places, {} nodes, {} edges) to {}",
            map.name,
            map.num_places(),
            inst.spn.nodes.len(),
            inst.spn.num_edges(),
            p.display()
        );
    }
    Ok(())
}
