//! `graphspn infer`: posterior class marginals (and optionally the MPE labelling) of
//! every place of a map, given per-place evidence, through the instance GraphSPN.
//!
//! Evidence file (JSON): `{"format": 1, "evidence": {"<place id>": [α per class], …}}`.
//! α are non-negative class likelihoods (need not sum to 1, not all 0); places not
//! listed get α = 1 for every class (no evidence), so the reported log-likelihood is
//! ln P(evidence of the listed places).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use graphspn_compiler::map::TopoMap;
use graphspn_compiler::render::{RenderOptions, render_svg};
use serde::Deserialize;
use serde_json::json;

use super::common::{component_instance_for, data_dir, load_map};

/// Version of the evidence file format.
pub const EVIDENCE_FORMAT: u32 = 1;

/// Arguments of `graphspn infer`.
#[derive(Args)]
pub struct InferArgs {
    /// Model file written by `graphspn train`.
    #[arg(long)]
    model: PathBuf,
    /// The map: a JSON map, a COLD sequence folder, or a sequence name under --data.
    #[arg(long)]
    map: PathBuf,
    /// Evidence file (JSON, see the module documentation); without it, no evidence.
    #[arg(long)]
    evidence: Option<PathBuf>,
    /// Folder holding the COLD buildings (default: $GRAPHSPN_DATA).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Number of decompositions mixed by the instance.
    #[arg(long, default_value_t = 5)]
    decompositions: usize,
    /// Seed of the decompositions.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Write the result JSON here instead of standard output.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also compute the max-product (MPE) labelling.
    #[arg(long)]
    mpe: bool,
    /// Draw the map with one pie chart of the marginals per place.
    #[arg(long)]
    svg: Option<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EvidenceFile {
    format: u32,
    evidence: BTreeMap<String, Vec<f64>>,
}

/// Line (1-based) of the first occurrence of `"key"` followed by `:` in `text`.
fn line_of_key(text: &str, key: &str) -> Option<usize> {
    let quoted = format!("\"{key}\"");
    text.lines()
        .position(|l| {
            l.find(&quoted)
                .is_some_and(|i| l[i + quoted.len()..].trim_start().starts_with(':'))
        })
        .map(|i| i + 1)
}

/// Parses an evidence file for `map`: one row per place (place order), all ones (no
/// evidence) where none is given. Errors name the file, the line and the place id.
pub fn parse_evidence(text: &str, file: &Path, map: &TopoMap) -> Result<Vec<Vec<f64>>> {
    let f: EvidenceFile = serde_json::from_str(text)
        .with_context(|| format!("{}: not a valid evidence file", file.display()))?;
    if f.format != EVIDENCE_FORMAT {
        bail!(
            "{}: evidence format {} (this tool reads format {EVIDENCE_FORMAT})",
            file.display(),
            f.format
        );
    }
    let c = map.classes.len();
    let mut rows = vec![vec![1.0; c]; map.num_places()];
    for (key, row) in &f.evidence {
        let at = || match line_of_key(text, key) {
            Some(l) => format!("{}:{l}", file.display()),
            None => file.display().to_string(),
        };
        let id: u32 = key
            .parse()
            .with_context(|| format!("{}: {key:?} is not a place id", at()))?;
        let Some(i) = map.index_of_id(id) else {
            bail!("{}: place id {id} is not in map {:?}", at(), map.name);
        };
        if row.len() != c {
            bail!(
                "{}: place id {id} has {} likelihoods, the map has {c} classes ({})",
                at(),
                row.len(),
                map.classes.names().join(", ")
            );
        }
        if let Some(k) = row.iter().position(|a| !a.is_finite() || *a < 0.0) {
            bail!(
                "{}: place id {id}: likelihood of class {} is {} (must be finite and >= 0)",
                at(),
                map.classes.name(k as u16),
                row[k]
            );
        }
        if row.iter().all(|&a| a == 0.0) {
            bail!("{}: place id {id}: every likelihood is 0", at());
        }
        rows[i] = row.clone();
    }
    Ok(rows)
}

/// Runs `graphspn infer`.
pub fn run(args: InferArgs) -> Result<()> {
    let map = load_map(&args.map, data_dir(args.data))?;
    let rows = match &args.evidence {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            parse_evidence(&text, p, &map)?
        }
        None => vec![vec![1.0; map.classes.len()]; map.num_places()],
    };
    let mut im = component_instance_for(&args.model, &map, args.decompositions, args.seed)?;
    im.set_all_evidence(&rows).context("setting the evidence")?;
    let m = im.marginals().context("computing marginals")?;
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
    let places: Vec<_> = map
        .places()
        .zip(&m.probs)
        .map(|(p, row)| json!({"id": p.id, "argmax": names[argmax(row)], "probs": row}))
        .collect();
    let mut doc = json!({
        "format": 1,
        "map": map.name,
        "classes": names,
        "decompositions": args.decompositions,
        "seed": args.seed,
        "log_likelihood": m.log_likelihood,
        "places": places,
    });
    if args.mpe {
        let mpe = im.mpe(&[]).context("computing the MPE labelling")?;
        let labels: BTreeMap<String, &str> = map
            .places()
            .zip(&mpe.assignment)
            .map(|(p, &k)| (p.id.to_string(), names[k as usize].as_str()))
            .collect();
        doc["mpe"] = json!({
            "labels": labels,
            "log_max_product": mpe.log_max_product,
            "log_probability": mpe.log_probability,
        });
    }
    let text = serde_json::to_string_pretty(&doc)? + "\n";
    match &args.out {
        Some(p) => {
            std::fs::write(p, &text).with_context(|| format!("writing {}", p.display()))?;
            eprintln!(
                "wrote marginals of {} places to {}",
                map.num_places(),
                p.display()
            );
        }
        None => super::common::write_stdout(&text)?,
    }
    if let Some(svg) = &args.svg {
        let opts = RenderOptions {
            title: Some(format!("{}: GraphSPN marginals", map.name)),
            distributions: Some(&m.probs),
            ..RenderOptions::default()
        };
        std::fs::write(svg, render_svg(&map, &opts))
            .with_context(|| format!("writing {}", svg.display()))?;
        eprintln!("wrote {}", svg.display());
    }
    Ok(())
}
