//! `graphspn evaluate`: the paper's protocol (classification, placeholders, novelty)
//! on a user's own maps, against the validated baselines.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use graphspn_compiler::experiments::report::write_outputs;
use graphspn_compiler::experiments::reproduce::run;
use graphspn_compiler::map::{TopoMap, cold, load_map_set_report, map_set_name};

use super::common::{flag_domain, require_data_dir};
use super::output::{Outputs, write_folder};
use super::reproduce::{ProtocolOptions, RunOptions, read_settings};

/// Arguments of `graphspn evaluate`.
#[derive(Args)]
#[command(after_help = "Examples:
  graphspn evaluate --maps my_building/ --out eval/
  graphspn evaluate --maps floor1.json --maps floor2.json --levels 2,5 --rounds 3 --out eval/
  graphspn evaluate --maps siteA/ --train siteB/ --train siteC/ --out eval/
  graphspn evaluate --maps heldout/ --train data/cold-topomaps/Freiburg --train data/cold-topomaps/Saarbrucken --settings val/validation.json --settings-of Stockholm --out eval/

Each --maps path is one test building: a JSON map, a COLD sequence folder, or a folder
of JSON maps and/or COLD sequence folders. Maps need a ground-truth class for every
place (the evidence is simulated from it, as in the paper's protocol) and the models'
class set. Models are trained on the --train buildings (default: the three COLD
buildings), every model's settings chosen by leave-one-training-building-out
validation on them (or taken from a saved validation with --settings); the --maps
buildings are never read before testing.")]
pub struct EvaluateArgs {
    /// A test building (repeatable): JSON map, COLD sequence folder, or folder of maps.
    #[arg(long = "maps", required = true)]
    maps: Vec<PathBuf>,
    /// A training building (repeatable, at least two for the validation); default:
    /// Freiburg, Saarbrucken and Stockholm from the COLD data folder.
    #[arg(long = "train")]
    train: Vec<PathBuf>,
    /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA, else the shipped data/cold-topomaps).
    #[arg(long)]
    data: Option<PathBuf>,
    #[command(flatten)]
    run: RunOptions,
    #[command(flatten)]
    protocol: ProtocolOptions,
    /// Test maps per building (default: all), chosen at random (seeded).
    #[arg(long)]
    max_maps: Option<usize>,
    /// Use the settings of a saved validation (`graphspn validate --out DIR` writes
    /// DIR/validation.json) for every test building instead of validating again. They
    /// must come from a validation on the same training buildings.
    #[arg(long)]
    settings: Option<PathBuf>,
    /// Which entry of --settings to use (the test building it was validated for);
    /// needed when the file holds more than one.
    #[arg(long, requires = "settings")]
    settings_of: Option<String>,
}

/// Loads the map sets of `paths` under their names; `flag` names them in errors.
fn load_sets(flag: &str, paths: &[PathBuf]) -> Result<Vec<(String, Vec<TopoMap>)>> {
    let mut out: Vec<(String, Vec<TopoMap>)> = Vec::new();
    for p in paths {
        let name = map_set_name(p);
        if out.iter().any(|(n, _)| *n == name) {
            bail!(
                "{flag} {}: another {flag} path is also called {name:?} (buildings are reported by folder or file name)",
                p.display()
            );
        }
        // A sub-folder that is not a COLD sequence is an error naming it (it was
        // skipped without a word); files that are not maps are named in a warning.
        let (maps, not_read) =
            load_map_set_report(p).with_context(|| format!("{flag} {}", p.display()))?;
        if !not_read.is_empty() {
            let names: Vec<String> = not_read
                .iter()
                .take(10)
                .map(|f| f.display().to_string())
                .collect();
            eprintln!(
                "warning: {flag} {}: {} file(s) not read (only *.json maps and COLD sequence folders are): {}{}",
                p.display(),
                not_read.len(),
                names.join(", "),
                if not_read.len() > 10 { ", …" } else { "" }
            );
        }
        out.push((name, maps));
    }
    Ok(out)
}

/// Runs `graphspn evaluate`.
pub fn run_cmd(args: EvaluateArgs) -> Result<()> {
    // Every argument and the output folder are checked before any computation.
    let mut outputs = Outputs::new(args.run.force);
    for p in &args.maps {
        if !p.exists() {
            bail!("--maps {}: no such file or folder", p.display());
        }
        outputs.input("--maps", p);
    }
    for p in &args.train {
        if !p.exists() {
            bail!("--train {}: no such file or folder", p.display());
        }
        outputs.input("--train", p);
    }
    let data = if args.train.is_empty() {
        let d = require_data_dir(args.data.clone())?;
        outputs.input("--data", &d);
        Some(d)
    } else {
        if args.data.is_some() {
            bail!(
                "--data: not used when --train is given (the training buildings are the --train paths)"
            );
        }
        None
    };
    if args.train.len() == 1 {
        bail!(
            "--train: give at least two training buildings (the validation trains on one and validates on another), or none for the three COLD buildings"
        );
    }
    outputs.folder("--out", &args.run.out)?;
    let mut cfg = args.run.config(false);
    args.protocol.apply(&mut cfg)?;
    if let Some(m) = args.max_maps {
        flag_domain(
            "--max-maps",
            graphspn_compiler::domain::maps("maps_per_building", m),
        )?;
        cfg.maps_per_building = m;
    }

    let chosen = match &args.settings {
        Some(p) => {
            outputs.input("--settings", p);
            let all = read_settings(p)?;
            let key = match (&args.settings_of, all.len()) {
                (Some(k), _) => k.clone(),
                (None, 1) => all.keys().next().cloned().unwrap_or_default(),
                (None, n) => bail!(
                    "--settings {}: holds the settings of {n} test buildings ({}); pick one with --settings-of",
                    p.display(),
                    all.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            };
            let Some(s) = all.get(&key) else {
                bail!(
                    "--settings-of {key}: {} holds settings for {} only",
                    p.display(),
                    all.keys().cloned().collect::<Vec<_>>().join(", ")
                );
            };
            Some(s.clone())
        }
        None => None,
    };
    let start = Instant::now();
    let tests = load_sets("--maps", &args.maps)?;
    let train = match &data {
        Some(d) => cold::BUILDINGS
            .iter()
            .map(|b| Ok((b.to_string(), cold::load_building(d, b)?)))
            .collect::<Result<Vec<_>>>()?,
        None => load_sets("--train", &args.train)?,
    };
    let mut all: BTreeMap<String, Vec<TopoMap>> = BTreeMap::new();
    let classes = &train[0].1[0].classes;
    for (flag, sets) in [("--train", &train), ("--maps", &tests)] {
        for (name, maps) in sets.iter() {
            if all.contains_key(name) {
                bail!(
                    "{flag}: a test and a training building are both called {name:?}; rename one folder"
                );
            }
            for m in maps {
                if &m.classes != classes {
                    bail!(
                        "{flag}: map {:?} has classes {:?}, but the training maps have {:?}",
                        m.name,
                        m.classes.names(),
                        classes.names()
                    );
                }
                if flag == "--maps"
                    && let Some(p) = m.places().find(|p| p.class.is_none())
                {
                    bail!(
                        "--maps: map {:?}, place {}: no ground-truth class (evaluation simulates evidence from the true classes)",
                        m.name,
                        p.id
                    );
                }
            }
            all.insert(name.clone(), maps.clone());
        }
    }
    cfg.test_buildings = tests.iter().map(|(n, _)| n.clone()).collect();
    cfg.train_buildings = Some(train.iter().map(|(n, _)| n.clone()).collect());
    if let Some(s) = chosen {
        cfg.settings = Some(
            cfg.test_buildings
                .iter()
                .map(|b| (b.clone(), s.clone()))
                .collect(),
        );
    }
    let (mut rep, setups) = run(&all, &cfg)?;
    rep.seconds = start.elapsed().as_secs_f64();
    write_folder(&args.run.out, |dir| {
        Ok(write_outputs(&rep, &setups, &cfg, dir, "")?)
    })?;
    eprintln!(
        "evaluation done in {:.1} s; wrote {}",
        start.elapsed().as_secs_f64(),
        args.run.out.join("REPORT.md").display()
    );
    Ok(())
}
