//! `graphspn infer`: posterior class marginals (and optionally the MPE labelling) of
//! every place of a map, given per-place evidence, through the instance GraphSPN or
//! the tree mixture (whichever family the model file holds).
//!
//! Evidence file (JSON): `{"format": 1, "evidence": {"<place id>": [α per class], …}}`.
//! α are non-negative class likelihoods (need not sum to 1, not all 0); places not
//! listed get α = 1 for every class (no evidence). The reported log-likelihood is the
//! model's `ln Σ_y P(y) Π_v α_v(y_v)` (a tree mixture raises the rows to its evidence
//! exponent γ first). `docs/FORMATS.md` describes the file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use graphspn_compiler::render::{RenderOptions, render_svg};
use serde::Serialize;
use serde_json::json;

use super::budget::{Budget, Work, candidates, read_map_within};
use super::evidence::read_evidence;
use super::flag_checks::{
    check_decomposition_count, check_trees_flag, parse_strategy, refuse_graphspn_flags,
};
use super::map_input::{any_map_fits, data_dir, declare_map};
use super::model_input::{
    component_instance_of, count_decompositions_file, decompositions_for, load_any_model,
};
use super::output::{Outputs, write_files};
use graphspn_compiler::decompose::DecompositionStrategy;
use graphspn_compiler::family::AnyModel;
use graphspn_compiler::interpreter::{Marginals, Mpe};
use graphspn_compiler::spn::Mixing;
use graphspn_compiler::treemix::TreeInstance;

/// Parses `--mixing` (`posterior` or `average`).
fn parse_mixing(s: &str) -> Result<Mixing, String> {
    Mixing::from_name(s).ok_or_else(|| format!("unknown mixing {s:?}: give posterior or average"))
}

/// Arguments of `graphspn infer`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn infer --model generated/demo/model.json --map generated/demo/floor.json
  graphspn infer --model model.json --map Freiburg/seq1_cloudy1 --evidence ev.json --mpe --out result.json --svg result.svg
  graphspn infer --model generated/demo/tree_model.json --map generated/demo/floor.json --trees 4

Evidence file (JSON; docs/FORMATS.md):
  {\"format\": 1, \"evidence\": {\"12\": [0.1, 0.9, 0, 0, 0, 0, 0, 0, 0, 0]}}
one row per place id, one non-negative likelihood per class of the map (in the map's
class order, not all 0; need not sum to 1). Places not listed have no evidence."
)]
pub struct InferArgs {
    /// Model file written by `graphspn train` (a GraphSPN or a tree mixture).
    #[arg(long)]
    model: PathBuf,
    /// The map: a JSON map, a COLD sequence folder, or a sequence name under --data.
    #[arg(long)]
    map: PathBuf,
    /// Evidence file (JSON): {"format": 1, "evidence": {"<place id>": [likelihood per
    /// class], ...}}; without it, no evidence. See the example below.
    #[arg(long)]
    evidence: Option<PathBuf>,
    /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    /// GraphSPN: number of decompositions mixed by the instance (1..=1000; default 5).
    #[arg(long)]
    decompositions: Option<usize>,
    /// Read the decompositions from this file (written by `graphspn decompose`)
    /// instead of making them.
    #[arg(long, conflicts_with_all = ["decompositions", "seed"])]
    decompositions_file: Option<PathBuf>,
    /// Seed of the decompositions (GraphSPN) or of the spanning trees (tree mixture).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// GraphSPN: how decompositions are drawn: `paper` (the authors' scheme) or
    /// `cover` (frontier places join their neighbour's component rather than stay
    /// alone; default paper).
    #[arg(long, value_parser = parse_strategy, conflicts_with = "decompositions_file")]
    strategy: Option<DecompositionStrategy>,
    /// Tree mixture: spanning trees mixed (1..=64; default: the model's).
    #[arg(long)]
    trees: Option<usize>,
    /// Write the result JSON here instead of standard output.
    #[arg(long)]
    out: Option<PathBuf>,
    /// How the decompositions' (or trees') marginals are mixed: `posterior` (the exact
    /// marginals of the mixture) or `average` (the mean of each component's exact
    /// marginals; the log-likelihood stays the mixture's). Default: posterior for
    /// GraphSPN, the model's own for a tree mixture.
    #[arg(long, value_parser = parse_mixing)]
    mixing: Option<Mixing>,
    /// Also compute the max-product (MPE) labelling: the labels of the most probable
    /// joint choice of labels and the model's hidden choices, which need not be the
    /// most probable labelling (docs/FORMATS.md).
    #[arg(long)]
    mpe: bool,
    /// Draw the map with one pie chart of the marginals per place.
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Replace existing --out / --svg files.
    #[arg(long)]
    force: bool,
}

/// One place of `infer`'s result.
#[derive(Serialize)]
struct PlaceOut<'a> {
    argmax: &'a str,
    id: u32,
    probs: &'a [f64],
}

/// The MPE labelling in `infer`'s result.
#[derive(Serialize)]
struct MpeOut<'a> {
    labels: BTreeMap<String, &'a str>,
    log_max_product: f64,
    log_probability: f64,
}

/// Places of a COLD map that its loading dropped, by reason (ids ascending).
#[derive(Serialize)]
struct DroppedOut<'a> {
    unknown: &'a [u32],
    isolated: &'a [u32],
    disconnected: &'a [u32],
}

/// `infer`'s result (`docs/FORMATS.md`).
#[derive(Serialize)]
struct InferOut<'a> {
    classes: &'a [String],
    /// What the COLD filtering dropped from the map; none when nothing was dropped.
    #[serde(skip_serializing_if = "Option::is_none")]
    dropped: Option<DroppedOut<'a>>,
    format: u32,
    log_likelihood: f64,
    map: &'a str,
    model: serde_json::Value,
    #[serde(skip_serializing_if = "Option::is_none")]
    mpe: Option<MpeOut<'a>>,
    places: Vec<PlaceOut<'a>>,
    /// The seed of the decompositions or trees; none when they were read from
    /// `--decompositions-file` (named in `model`).
    #[serde(skip_serializing_if = "Option::is_none")]
    seed: Option<u64>,
}

/// Runs `graphspn infer`.
pub fn run(args: InferArgs) -> Result<()> {
    // Every argument and input is checked before any work or write.
    let mut outputs = Outputs::new(args.force);
    outputs.input_file("--model", &args.model)?;
    let map_path = declare_map(&args.map, data_dir(args.data), &mut outputs)?;
    if let Some(p) = &args.evidence {
        outputs.input_file("--evidence", p)?;
    }
    if let Some(f) = &args.decompositions_file {
        // Checked by `count_decompositions_file` once the model is known to be a GraphSPN.
        outputs.input("--decompositions-file", f);
    }
    if let Some(p) = &args.out {
        outputs.file("--out", p)?;
    }
    if let Some(p) = &args.svg {
        outputs.file("--svg", p)?;
    }
    let model = load_any_model(&args.model)?;
    // The family's flags, and what will be built, before the map is read.
    let budget = match &model {
        AnyModel::Graphspn(model) => {
            check_trees_flag(args.trees, true)?;
            let classes = model.classes.len();
            match &args.decompositions_file {
                Some(f) => {
                    let count = count_decompositions_file("--decompositions-file", f)?;
                    let work = Work::Components {
                        count,
                        candidates: 0,
                        classes,
                    };
                    Budget::new(
                        format!(
                            "--decompositions-file {} ({count} decompositions)",
                            f.display()
                        ),
                        work,
                    )
                }
                None => {
                    let count = args.decompositions.unwrap_or(5);
                    check_decomposition_count("--decompositions", count)?;
                    let work = Work::Components {
                        count,
                        candidates: candidates(count),
                        classes,
                    };
                    Budget::new(format!("--decompositions {count}"), work)
                }
            }
        }
        AnyModel::TreeMixture(model) => {
            refuse_graphspn_flags(&[
                ("--decompositions", args.decompositions.is_some()),
                ("--decompositions-file", args.decompositions_file.is_some()),
                ("--strategy", args.strategy.is_some()),
            ])?;
            check_trees_flag(args.trees, false)?;
            let trees = args.trees.unwrap_or(model.trees);
            let work = Work::Trees {
                trees,
                classes: model.classes.len(),
            };
            Budget::new(format!("--trees {trees}"), work)
        }
    };
    let loaded = read_map_within("--map", &map_path, &budget)?;
    let map = &loaded.map;
    any_map_fits(&model, map, &map_path, &args.model)?;
    let rows = match &args.evidence {
        Some(p) => read_evidence(p, map, &loaded.dropped)?,
        None => vec![vec![1.0; map.classes.len()]; map.num_places()],
    };
    // What the queries ran on, for their errors (zero likelihood names the file).
    let on = match &args.evidence {
        Some(p) => format!("the evidence of --evidence {}", p.display()),
        None => "no evidence".to_string(),
    };
    let (m, mpe, mixture) = match &model {
        AnyModel::Graphspn(model) => {
            let count = args.decompositions.unwrap_or(5);
            let decs = decompositions_for(
                model,
                map,
                args.decompositions_file.as_deref(),
                count,
                args.seed,
                args.strategy.unwrap_or_default(),
            )?;
            let count = decs.len();
            // Component-wise evaluation against the shared template networks: memory
            // linear in places (the explicit instance SPN copies every weight per component).
            let mut im = component_instance_of(model, map, decs)?;
            im.set_all_evidence(&rows)
                .with_context(|| format!("setting {on}"))?;
            let mixing = args.mixing.unwrap_or_default();
            let m = im
                .marginals_mixed(mixing)
                .with_context(|| format!("computing marginals of {on}"))?;
            let mpe = match args.mpe {
                true => Some(
                    im.mpe(&[])
                        .with_context(|| format!("computing the MPE labelling of {on}"))?,
                ),
                false => None,
            };
            (m, mpe, {
                let mut doc = json!({"family": "graphspn", "decompositions": count,
                        "mixing": mixing.name()});
                if let Some(f) = &args.decompositions_file {
                    doc["decompositions_file"] = json!(f.display().to_string());
                }
                doc
            })
        }
        AnyModel::TreeMixture(model) => {
            let mut model = model.clone();
            if let Some(t) = args.trees {
                model.trees = t;
            }
            let mixing = args.mixing.unwrap_or(model.mixing);
            let mut inst = TreeInstance::with_covering_trees(&model, map, args.seed)?;
            inst.set_all_evidence(&rows)
                .with_context(|| format!("setting {on}"))?;
            let m = inst
                .marginals_mixed(mixing)
                .with_context(|| format!("computing marginals of {on}"))?
                .mixed;
            let mpe = match args.mpe {
                true => Some(
                    inst.mpe(&vec![None; map.num_places()])
                        .with_context(|| format!("computing the MPE labelling of {on}"))?,
                ),
                false => None,
            };
            let (covered, edges) = inst.trees().coverage(map);
            let doc = json!({
                "family": "tree_mixture",
                "trees": model.trees,
                "edges_covered": covered,
                "edges": edges,
                "mixing": mixing.name(),
            });
            (m, mpe, doc)
        }
    };
    let m: Marginals = m;
    let mpe: Option<Mpe> = mpe;
    let names = map.classes.names();
    let argmax = |row: &[f64]| {
        let mut best = 0;
        for (k, &p) in row.iter().enumerate() {
            if p > row[best] {
                best = k;
            }
        }
        best
    };
    // Written from borrowed data (a `serde_json::Value` of every place took 190 MB at
    // 100,000 places); fields in alphabetical order, as a JSON object prints them.
    let places: Vec<PlaceOut> = map
        .places()
        .zip(&m.probs)
        .map(|(p, row)| PlaceOut {
            argmax: &names[argmax(row)],
            id: p.id,
            probs: row,
        })
        .collect();
    let mpe = mpe.map(|mpe| MpeOut {
        labels: map
            .places()
            .zip(&mpe.assignment)
            .map(|(p, &k)| (p.id.to_string(), names[k as usize].as_str()))
            .collect(),
        log_max_product: mpe.log_max_product,
        log_probability: mpe.log_probability,
    });
    let d = &loaded.dropped;
    let nothing_dropped =
        d.unknown.is_empty() && d.isolated.is_empty() && d.disconnected.is_empty();
    let doc = InferOut {
        classes: names,
        dropped: (!nothing_dropped).then_some(DroppedOut {
            unknown: &d.unknown,
            isolated: &d.isolated,
            disconnected: &d.disconnected,
        }),
        format: 1,
        log_likelihood: m.log_likelihood,
        map: &map.name,
        model: mixture,
        mpe,
        places,
        seed: args.decompositions_file.is_none().then_some(args.seed),
    };
    let text = serde_json::to_string_pretty(&doc)? + "\n";
    let svg = args.svg.as_ref().map(|_| {
        let opts = RenderOptions {
            title: Some(format!(
                "{}: {} marginals",
                map.name,
                match model.family() {
                    graphspn_compiler::family::ModelFamily::Graphspn => "GraphSPN",
                    graphspn_compiler::family::ModelFamily::TreeMixture => "tree-mixture",
                }
            )),
            distributions: Some(&m.probs),
            ..RenderOptions::default()
        };
        render_svg(map, &opts)
    });
    let mut files: Vec<(&Path, &[u8])> = Vec::new();
    if let Some(p) = &args.out {
        files.push((p, text.as_bytes()));
    }
    if let (Some(p), Some(s)) = (&args.svg, &svg) {
        files.push((p, s.as_bytes()));
    }
    write_files(&files)?;
    if let Some(p) = &args.out {
        eprintln!(
            "wrote marginals of {} places to {}",
            map.num_places(),
            p.display()
        );
    } else {
        super::output::write_stdout(&text)?;
    }
    if let Some(p) = &args.svg {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
