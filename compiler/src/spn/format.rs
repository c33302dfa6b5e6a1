//! The versioned JSON file format of an [`Spn`]:
//! `{"format": 1, "classes": [...], "root": N, "nodes": [...]}`.
//!
//! Output is pretty-printed with a fixed field order, so the same SPN always gives
//! the same bytes. Floats are written in their shortest round-trip form and parsed
//! with `serde_json`'s `float_roundtrip` feature, so weights survive a round trip
//! bit for bit.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::validate::SpnError;
use super::{Node, NodeId, Spn};

/// The only format version this build reads and writes.
pub const SPN_FORMAT_VERSION: u32 = 1;

/// Why an SPN file could not be read.
#[derive(Debug, Error)]
pub enum SpnFormatError {
    /// The text is not valid JSON or does not have the SPN file's shape.
    #[error(
        "invalid SPN JSON at line {line}, column {column}: {}",
        crate::json_error::json_message(source)
    )]
    Json {
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// The `format` field is missing.
    #[error("SPN JSON has no \"format\" field (expected \"format\": {SPN_FORMAT_VERSION})")]
    MissingVersion,
    /// The file's format version is not supported.
    #[error(
        "unsupported SPN format version {found} (this build reads only format {SPN_FORMAT_VERSION})"
    )]
    UnsupportedVersion {
        /// The version in the file, as written there.
        found: String,
    },
    /// The file parsed but the SPN is invalid.
    #[error("the SPN in the file is invalid: {0}")]
    Invalid(#[from] SpnError),
}

impl From<serde_json::Error> for SpnFormatError {
    fn from(source: serde_json::Error) -> Self {
        SpnFormatError::Json {
            line: source.line(),
            column: source.column(),
            source,
        }
    }
}

#[derive(Serialize)]
struct FileOut<'a> {
    format: u32,
    classes: &'a [u32],
    root: NodeId,
    nodes: &'a [Node],
}

#[derive(Deserialize)]
struct Header {
    format: Option<serde_json::Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileIn {
    #[allow(dead_code)]
    format: u32,
    classes: Vec<u32>,
    root: NodeId,
    nodes: Vec<Node>,
}

impl Spn {
    /// The SPN as pretty-printed JSON in format version [`SPN_FORMAT_VERSION`].
    pub fn to_json(&self) -> String {
        let file = FileOut {
            format: SPN_FORMAT_VERSION,
            classes: &self.classes,
            root: self.root,
            nodes: &self.nodes,
        };
        // Serialising plain data (no maps with non-string keys) cannot fail.
        serde_json::to_string_pretty(&file).unwrap_or_default()
    }

    /// Parses and validates ([`Spn::validate`]) an SPN written by [`Spn::to_json`].
    pub fn from_json(text: &str) -> Result<Spn, SpnFormatError> {
        let header: Header = serde_json::from_str(text)?;
        match header.format {
            None => return Err(SpnFormatError::MissingVersion),
            Some(v) if v.as_u64() == Some(u64::from(SPN_FORMAT_VERSION)) => {}
            Some(v) => {
                return Err(SpnFormatError::UnsupportedVersion {
                    found: v.to_string(),
                });
            }
        }
        let file: FileIn = serde_json::from_str(text)?;
        let spn = Spn {
            classes: file.classes,
            nodes: file.nodes,
            root: file.root,
        };
        spn.validate()?;
        Ok(spn)
    }
}
