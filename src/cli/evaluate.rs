//! `graphspn evaluate`: the paper's protocol (classification, placeholders, novelty)
//! on a user's own maps, against the validated baselines.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use graphspn_compiler::experiments::report::write_outputs;
use graphspn_compiler::experiments::reproduce::run;
use graphspn_compiler::experiments::sets::{Evaluation, MapSet, NameRequest, SetRole, name_sets};
use graphspn_compiler::map::{TopoMap, cold, load_map_set_report, map_set_name, shown_class_names};

use super::flag_checks::flag_domain;
use super::map_input::{load_buildings, require_data_dir, warn_dropped};
use super::output::{Outputs, write_folder};
use super::reproduce::{ProtocolOptions, RunOptions, read_settings};

/// Arguments of `graphspn evaluate`.
#[derive(Args)]
#[command(after_help = "Examples:
  graphspn evaluate --maps my_building/ --out eval/
  graphspn evaluate --maps floor1.json --maps floor2.json --levels 2,5 --rounds 3 --out eval/
  graphspn evaluate --maps siteA/ --train siteB/ --train siteC/ --out eval/
  graphspn evaluate --maps new_stockholm=maps/Stockholm --out eval/
  graphspn evaluate --maps heldout/ --train data/cold-topomaps/Freiburg --train data/cold-topomaps/Saarbrucken --settings val/validation.json --settings-of Stockholm --out eval/

Each --maps path is one test building: a JSON map, a COLD sequence folder, or a folder
of JSON maps and/or COLD sequence folders. Maps need a ground-truth class for every
place (the evidence is simulated from it, as in the paper's protocol) and the models'
class set. Models are trained on the --train buildings (default: the three COLD
buildings), every model's settings chosen by leave-one-training-building-out
validation on them (or taken from a saved validation with --settings); the --maps
buildings are never read before testing.

Sets are reported under their folder or file names. A test folder called like a training
building (e.g. your own Stockholm maps in a folder `Stockholm`, beside the bundled COLD
Stockholm) is reported as NAME-test, and REPORT.md lists which set is which; give
--maps NAME=PATH (or --train NAME=PATH) to choose a name yourself. A set's name also
seeds its evidence draws and the validation's (with --seed): renaming a set draws other
evidence, and renaming a training set can change the settings the validation picks.")]
pub struct EvaluateArgs {
    /// A test building (repeatable): JSON map, COLD sequence folder, or folder of maps;
    /// NAME=PATH reports it as NAME (default: the folder or file name).
    #[arg(long = "maps", required = true)]
    maps: Vec<PathBuf>,
    /// A training building (repeatable, at least two for the validation; NAME=PATH
    /// names it); default: Freiburg, Saarbrucken and Stockholm from the COLD data folder.
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

/// A `--maps`/`--train` argument: `PATH`, or `NAME=PATH` to choose the name the set is
/// reported under. A path that exists as written is a path even if it holds `=`.
struct SetArg {
    /// The argument as given, for messages.
    given: String,
    /// The name chosen with `NAME=PATH`.
    name: Option<String>,
    /// The map set's path.
    path: PathBuf,
}

fn parse_set_arg(flag: &str, arg: &Path) -> Result<SetArg> {
    let given = arg.display().to_string();
    if !arg.exists()
        && let Some((name, path)) = given.split_once('=')
    {
        let path = PathBuf::from(path);
        if !path.exists() {
            bail!("{flag} {given}: no such file or folder {}", path.display());
        }
        return Ok(SetArg {
            name: Some(name.to_string()),
            given,
            path,
        });
    }
    if !arg.exists() {
        bail!("{flag} {given}: no such file or folder");
    }
    Ok(SetArg {
        given,
        name: None,
        path: arg.to_path_buf(),
    })
}

/// Refuses two set arguments that read the same maps: the same file or folder given
/// twice, or a test set inside a training set (or the reverse).
fn check_disjoint(paths: &[(&str, String, SetRole, PathBuf)]) -> Result<()> {
    let canonical: Vec<Option<PathBuf>> = paths
        .iter()
        .map(|(_, _, _, p)| std::fs::canonicalize(p).ok())
        .collect();
    for i in 0..paths.len() {
        for j in i + 1..paths.len() {
            let (Some(a), Some(b)) = (&canonical[i], &canonical[j]) else {
                continue;
            };
            let (fa, ga, ra, _) = &paths[i];
            let (fb, gb, rb, _) = &paths[j];
            if a == b {
                bail!(
                    "{fa} {ga} and {fb} {gb}: the same maps are given twice{}; give each set once",
                    if ra != rb {
                        " (as test and as training maps)"
                    } else {
                        ""
                    }
                );
            }
            if ra != rb && (a.starts_with(b) || b.starts_with(a)) {
                bail!(
                    "{fa} {ga} and {fb} {gb}: one holds the other, so test maps would also be training maps; give folders that do not overlap"
                );
            }
        }
    }
    Ok(())
}

/// A map set to read: the flag and argument that name it, its role and path.
struct Source {
    flag: &'static str,
    /// The argument as given (for a bundled COLD building, its name).
    given: String,
    role: SetRole,
    path: PathBuf,
    /// One of the bundled COLD buildings (default training sets).
    bundled: bool,
}

/// Loads the map set at `path`; `flag` and `given` name it in errors and warnings.
fn load_set(flag: &str, given: &str, path: &Path) -> Result<Vec<TopoMap>> {
    // A sub-folder that is not a COLD sequence is an error naming it (it was
    // skipped without a word); files that are not maps, and maps that lost places to
    // disconnection, are named in warnings.
    let set = load_map_set_report(path).with_context(|| format!("{flag} {given}"))?;
    for (map, dropped) in set.maps.iter().zip(&set.dropped) {
        warn_dropped(&format!("{flag} {given}: map {}", map.name), map, dropped);
    }
    let not_read = set.not_read;
    if !not_read.is_empty() {
        let names: Vec<String> = not_read
            .iter()
            .take(10)
            .map(|f| f.display().to_string())
            .collect();
        eprintln!(
            "warning: {flag} {given}: {} file(s) not read (only *.json maps and COLD sequence folders are): {}{}",
            not_read.len(),
            names.join(", "),
            if not_read.len() > 10 { ", …" } else { "" }
        );
    }
    Ok(set.maps)
}

/// Runs `graphspn evaluate`.
pub fn run_cmd(args: EvaluateArgs) -> Result<()> {
    // Every argument and the output folder are checked before any computation.
    let mut outputs = Outputs::new(args.run.force);
    let test_args = args
        .maps
        .iter()
        .map(|p| parse_set_arg("--maps", p))
        .collect::<Result<Vec<_>>>()?;
    let train_args = args
        .train
        .iter()
        .map(|p| parse_set_arg("--train", p))
        .collect::<Result<Vec<_>>>()?;
    for (flag, sets) in [("--maps", &test_args), ("--train", &train_args)] {
        for a in sets {
            outputs.input(flag, &a.path);
        }
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
    if let Some(p) = &args.settings {
        outputs.input_file("--settings", p)?;
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
            let saved = read_settings(p)?;
            let all = &saved.settings;
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
            let s = s.clone();
            Some((saved, key, s))
        }
        None => None,
    };
    // Every set gets a distinct name before anything is read: the training buildings
    // keep theirs, a test folder called like one of them (or like another set) is
    // reported under a distinct name, and NAME=PATH chooses a name.
    let bundled: Vec<(String, PathBuf)> = match &data {
        Some(d) => cold::BUILDINGS
            .iter()
            .map(|b| (b.to_string(), d.join(b)))
            .collect(),
        None => Vec::new(),
    };
    let mut requests: Vec<NameRequest> = test_args
        .iter()
        .map(|a| NameRequest {
            role: SetRole::Test,
            given: a.name.clone(),
            stem: map_set_name(&a.path),
        })
        .collect();
    requests.extend(train_args.iter().map(|a| NameRequest {
        role: SetRole::Training,
        given: a.name.clone(),
        stem: map_set_name(&a.path),
    }));
    requests.extend(bundled.iter().map(|(b, _)| NameRequest {
        role: SetRole::Training,
        given: None,
        stem: b.clone(),
    }));
    // Names may be made distinct, but the same maps must not be both trained and
    // tested on (or tested twice): that is refused, naming both arguments.
    let mut paths: Vec<(&str, String, SetRole, PathBuf)> = Vec::new();
    for (flag, role, sets) in [
        ("--maps", SetRole::Test, &test_args),
        ("--train", SetRole::Training, &train_args),
    ] {
        for a in sets {
            paths.push((flag, a.given.clone(), role, a.path.clone()));
        }
    }
    for (b, p) in &bundled {
        paths.push((
            "--data",
            format!("{} (bundled {b})", p.display()),
            SetRole::Training,
            p.clone(),
        ));
    }
    check_disjoint(&paths)?;
    let names = name_sets(&requests).map_err(|e| anyhow::anyhow!("{e}"))?;
    let start = Instant::now();
    let mut sets: Vec<Source> = Vec::new();
    for (flag, role, args) in [
        ("--maps", SetRole::Test, &test_args),
        ("--train", SetRole::Training, &train_args),
    ] {
        sets.extend(args.iter().map(|a| Source {
            flag,
            given: a.given.clone(),
            role,
            path: a.path.clone(),
            bundled: false,
        }));
    }
    sets.extend(bundled.iter().map(|(b, p)| Source {
        flag: "--data",
        given: b.clone(),
        role: SetRole::Training,
        path: p.clone(),
        bundled: true,
    }));
    let mut loaded: Vec<Vec<TopoMap>> = Vec::new();
    for set in &sets {
        loaded.push(match (&data, set.bundled) {
            (Some(d), true) => load_buildings(d, std::slice::from_ref(&set.given))
                .with_context(|| format!("--data {}", d.display()))?,
            _ => load_set(set.flag, &set.given, &set.path)?,
        });
    }
    let first_train = sets
        .iter()
        .position(|s| s.role == SetRole::Training)
        .unwrap_or(0);
    let Some(classes) = loaded[first_train].first().map(|m| m.classes.clone()) else {
        bail!(
            "{} {}: holds no maps",
            sets[first_train].flag,
            sets[first_train].given
        );
    };
    let mut evaluation = Evaluation::default();
    let mut all: BTreeMap<String, Vec<TopoMap>> = BTreeMap::new();
    for ((set, maps), (name, note)) in sets.iter().zip(loaded).zip(names) {
        let (flag, given) = (set.flag, &set.given);
        for m in &maps {
            if m.classes != classes {
                bail!(
                    "{flag} {given}: map {:?} has classes {}, but the training maps have {}",
                    m.name,
                    shown_class_names(m.classes.names()),
                    shown_class_names(classes.names())
                );
            }
            if set.role == SetRole::Test && m.places().next().is_none() {
                bail!("{flag} {given}: map {:?} has no places", m.name);
            }
            if set.role == SetRole::Test
                && let Some(p) = m.places().find(|p| p.class.is_none())
            {
                bail!(
                    "{flag} {given}: map {:?}, place {}: no ground-truth class (evaluation simulates evidence from the true classes)",
                    m.name,
                    p.id
                );
            }
        }
        if let Some(n) = &note {
            eprintln!("note: {flag} {given}: {n}");
        }
        evaluation.sets.push(MapSet {
            name: name.clone(),
            role: set.role,
            source: set.path.display().to_string(),
            bundled: set.bundled,
            maps: maps.len(),
            note,
        });
        all.insert(name, maps);
    }
    cfg.test_buildings = evaluation
        .names(SetRole::Test)
        .into_iter()
        .map(str::to_string)
        .collect();
    cfg.train_buildings = Some(
        evaluation
            .names(SetRole::Training)
            .into_iter()
            .map(str::to_string)
            .collect(),
    );
    let mut given = None;
    if let Some((saved, key, s)) = chosen {
        let training = cfg.train_buildings.clone().unwrap_or_default();
        saved.check_training(&key, &training)?;
        cfg.settings = Some(
            cfg.test_buildings
                .iter()
                .map(|b| (b.clone(), s.clone()))
                .collect(),
        );
        given = Some(saved.given(std::slice::from_ref(&key), Some(key.clone())));
    }
    let (mut rep, setups) = run(&all, &cfg)?;
    rep.seconds = start.elapsed().as_secs_f64();
    rep.given_settings = given;
    rep.evaluation = Some(evaluation);
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
