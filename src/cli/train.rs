//! `graphspn train`: learn a model from annotated COLD maps.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use graphspn_compiler::family::ModelFamily;
use graphspn_compiler::learn::{Progress, SplitChoice, TrainingSettings, train_model};
use graphspn_compiler::mrf::Normalisation;
use graphspn_compiler::spn::Mixing;
use graphspn_compiler::template::Template;
use graphspn_compiler::treemix::{TreeTraining, train_tree_mixture};

use super::flag_checks::flag_error;
use super::map_input::{check_data_buildings, load_buildings, require_data_dir};
use super::output::{Outputs, write_files};

/// Arguments of `graphspn train`.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:
  graphspn train --out model.json
  graphspn train --buildings Freiburg,Saarbrucken,Stockholm --epochs 20 --seed 3 --out model.json --force
  graphspn train --family tree-mixture --coupling 1 --evidence-exponent 2 --trees 4 --out trees.json
  graphspn train --data my-data --buildings MyLab --out mylab.json   (my-data/MyLab/<sequence>/nodes.dat, rooms.dat)"
)]
pub struct TrainArgs {
    /// Folder of buildings, each a folder of COLD sequences: the shipped COLD maps
    /// (Freiburg/, Saarbrucken/, Stockholm/) or your own in the same layout (default:
    /// $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Buildings to train on (sub-folders of --data), comma-separated, each at most once.
    #[arg(long, value_delimiter = ',', default_value = "Freiburg,Saarbrucken")]
    buildings: Vec<String>,
    /// Output model file (JSON).
    #[arg(long)]
    out: PathBuf,
    /// GraphSPN: master seed of every random step of its training (default 0). The
    /// tree mixture's training has no random step and refuses it.
    #[arg(long)]
    seed: Option<u64>,
    /// EM epochs (1 to 10000; default 10).
    #[arg(long)]
    epochs: Option<usize>,
    /// Decompositions of each training map per template (1 to 1000; default 10).
    #[arg(long)]
    decompositions_per_map: Option<usize>,
    /// Template temperature: every sum weight raised to this power and renormalised
    /// after training (in (0, 10]; < 1 flattens the learned statistics; default 1, none).
    #[arg(long)]
    temperature: Option<f64>,
    /// How the dense template structure splits each region (`most_images`, the
    /// default: the Star's 8,000 weights with 10 classes; `fewest_images`: its 3,750,
    /// about two thirds of the compiled code's multiply-adds; `graphspn validate`
    /// searches both).
    #[arg(long, value_parser = parse_split)]
    star_split: Option<SplitChoice>,
    /// Model family: `graphspn` (the paper's template SPNs) or `tree-mixture` (a
    /// mixture of edge-covering spanning trees with one learned pairwise potential).
    #[arg(long, default_value = "graphspn", value_parser = parse_family)]
    family: ModelFamily,
    /// Tree mixture: potential form of the edge co-occurrence counts (`joint`,
    /// `normalised`, `pmi`; default normalised).
    #[arg(long, value_parser = parse_normalisation)]
    potential: Option<Normalisation>,
    /// Tree mixture: coupling exponent of the potential (in [0, 10]; default 1). The
    /// trained potential's largest/smallest entry may not exceed 1e6, which on the COLD
    /// maps limits the coupling to about 1.6-1.7 (1.4 with `--potential pmi`);
    /// training refuses a larger one, naming these flags.
    #[arg(long)]
    coupling: Option<f64>,
    /// Tree mixture: the unary potential is the training class shares to this power
    /// (in [-2, 2]; default 0, uniform).
    #[arg(long)]
    prior_exponent: Option<f64>,
    /// Tree mixture: evidence rows enter as α^γ with this integer γ (1 to 8; default 2).
    #[arg(long)]
    evidence_exponent: Option<u32>,
    /// Tree mixture: spanning trees per map (1 to 64; default 4).
    #[arg(long)]
    trees: Option<usize>,
    /// Tree mixture: how the trees' marginals are combined (`posterior` or
    /// `average`; default average).
    #[arg(long, value_parser = parse_mixing)]
    mixing: Option<Mixing>,
    /// Replace an existing output file.
    #[arg(long)]
    force: bool,
}

/// The tree-mixture settings the flags set.
const TREE_FLAGS: [(&str, &str); 5] = [
    ("potentials.normalisation", "--potential"),
    ("potentials.coupling", "--coupling"),
    ("prior_exponent", "--prior-exponent"),
    ("evidence_exponent", "--evidence-exponent"),
    ("trees", "--trees"),
];

/// The GraphSPN training settings the flags set.
const GRAPHSPN_FLAGS: [(&str, &str); 3] = [
    ("epochs", "--epochs"),
    ("decompositions_per_map", "--decompositions-per-map"),
    ("temperature", "--temperature"),
];

/// What `train` will learn.
enum Plan {
    Graphspn(TrainingSettings),
    Trees(TreeTraining),
}

fn parse_family(s: &str) -> Result<ModelFamily, String> {
    ModelFamily::from_name(s)
        .ok_or_else(|| format!("unknown family {s:?}: graphspn or tree-mixture"))
}

fn parse_normalisation(s: &str) -> Result<Normalisation, String> {
    Normalisation::ALL
        .into_iter()
        .find(|n| n.name() == s)
        .ok_or_else(|| format!("unknown potential {s:?}: joint, conditional, normalised or pmi"))
}

fn parse_split(s: &str) -> Result<SplitChoice, String> {
    SplitChoice::from_name(s)
        .ok_or_else(|| format!("unknown split {s:?}: most_images or fewest_images"))
}

fn parse_mixing(s: &str) -> Result<Mixing, String> {
    Mixing::from_name(s).ok_or_else(|| format!("unknown mixing {s:?}: posterior or average"))
}

/// Runs `graphspn train`.
pub fn run(args: TrainArgs) -> Result<()> {
    let data = require_data_dir(args.data)?;
    let mut outputs = Outputs::new(args.force);
    outputs.input("--data", &data);
    outputs.file("--out", &args.out)?;
    check_data_buildings("--buildings", &args.buildings, &data)?;
    let tree_flags = [
        ("--potential", args.potential.is_some()),
        ("--coupling", args.coupling.is_some()),
        ("--prior-exponent", args.prior_exponent.is_some()),
        ("--evidence-exponent", args.evidence_exponent.is_some()),
        ("--trees", args.trees.is_some()),
        ("--mixing", args.mixing.is_some()),
    ];
    let graphspn_flags = [
        ("--epochs", args.epochs.is_some()),
        (
            "--decompositions-per-map",
            args.decompositions_per_map.is_some(),
        ),
        ("--temperature", args.temperature.is_some()),
        ("--star-split", args.star_split.is_some()),
        ("--seed", args.seed.is_some()),
    ];
    let (wrong, family) = match args.family {
        ModelFamily::Graphspn => (tree_flags.as_slice(), "tree-mixture"),
        ModelFamily::TreeMixture => (graphspn_flags.as_slice(), "graphspn"),
    };
    if let Some((flag, _)) = wrong.iter().find(|f| f.1) {
        anyhow::bail!("{flag} applies to --family {family} only");
    }
    // The settings, checked against their domains before the maps are read.
    let settings = match args.family {
        ModelFamily::TreeMixture => {
            let mut t = TreeTraining::default();
            if let Some(p) = args.potential {
                t.potentials.normalisation = p;
            }
            if let Some(c) = args.coupling {
                t.potentials.coupling = c;
            }
            if let Some(r) = args.prior_exponent {
                t.prior_exponent = r;
            }
            if let Some(g) = args.evidence_exponent {
                t.evidence_exponent = g;
            }
            if let Some(n) = args.trees {
                t.trees = n;
            }
            if let Some(m) = args.mixing {
                t.mixing = m;
            }
            t.check().map_err(|e| flag_error(e, &TREE_FLAGS))?;
            Plan::Trees(t)
        }
        ModelFamily::Graphspn => {
            let mut settings = TrainingSettings::default();
            if let Some(s) = args.seed {
                settings.seed = s;
            }
            if let Some(e) = args.epochs {
                settings.epochs = e;
            }
            if let Some(d) = args.decompositions_per_map {
                settings.decompositions_per_map = d;
            }
            if let Some(t) = args.temperature {
                settings.temperature = t;
            }
            if let Some(c) = args.star_split {
                settings.structure.split_choice = c;
            }
            settings
                .check()
                .map_err(|e| flag_error(e, &GRAPHSPN_FLAGS))?;
            Plan::Graphspn(settings)
        }
    };
    let maps = load_buildings(&data, &args.buildings)?;
    // Where the maps came from (the model file names them `building/sequence`).
    let source = format!("{} in {}", args.buildings.join(", "), data.display());
    let settings = match settings {
        Plan::Graphspn(s) => s,
        Plan::Trees(t) => {
            let start = Instant::now();
            // The potential's spread is known only once counted: a coupling (or prior
            // exponent) inside its domain can still take it past MAX_POTENTIAL_RATIO.
            let model = train_tree_mixture(&maps, &t).with_context(|| {
                format!(
                    "--coupling {} --prior-exponent {} --potential {}: training the tree mixture (a smaller --coupling or |--prior-exponent| narrows the potentials)",
                    t.potentials.coupling,
                    t.prior_exponent,
                    t.potentials.normalisation.name()
                )
            })?;
            let text = model.to_json()?;
            write_files(&[(&args.out, text.as_bytes())])?;
            eprintln!(
                "trained a tree mixture ({}) on {} maps of {} in {:.2} s; wrote {}",
                t.label(),
                maps.len(),
                source,
                start.elapsed().as_secs_f64(),
                args.out.display()
            );
            return Ok(());
        }
    };
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
        "trained on {} maps of {} in {:.2} s; wrote {}",
        maps.len(),
        source,
        elapsed.as_secs_f64(),
        args.out.display()
    );
    Ok(())
}
