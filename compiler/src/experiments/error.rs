//! Why an experiment (validation, reproduction, evaluation) failed.

use thiserror::Error;

use crate::decompose::DecomposeError;
use crate::instance::InstanceQueryError;
use crate::learn::TrainModelError;
use crate::map::MapError;
use crate::mrf::MrfError;
use crate::noise::EvidenceSimError;
use crate::treemix::TreeMixError;

/// Why a reproduction run failed.
#[derive(Debug, Error)]
pub enum ReproduceError {
    /// Loading the maps failed.
    #[error("loading building {building}: {source}")]
    Load {
        /// Building name.
        building: String,
        /// What failed.
        source: MapError,
    },
    /// A configuration value is unusable.
    #[error("bad configuration: {0}")]
    Config(String),
    /// Training GraphSPN failed.
    #[error("training GraphSPN for test building {building}: {source}")]
    Train {
        /// Test building.
        building: String,
        /// What failed.
        source: TrainModelError,
    },
    /// Training an MRF failed, or its inference failed.
    #[error("MRF on {what}: {source}")]
    Mrf {
        /// Map / model.
        what: String,
        /// What failed.
        source: MrfError,
    },
    /// Decomposing a test map failed.
    #[error("decomposing test map {map}: {source}")]
    Decompose {
        /// Map name.
        map: String,
        /// What failed.
        source: DecomposeError,
    },
    /// Building an instance GraphSPN, or inference in it, failed.
    #[error("GraphSPN on {map}: {source}")]
    Inference {
        /// Map name.
        map: String,
        /// What failed.
        source: InstanceQueryError,
    },
    /// Training or querying a tree mixture failed.
    #[error("tree mixture on {what}: {source}")]
    Trees {
        /// Map / model.
        what: String,
        /// What failed.
        source: TreeMixError,
    },
    /// Evidence simulation failed.
    #[error("simulating evidence for {map}: {source}")]
    Evidence {
        /// Map name.
        map: String,
        /// What failed.
        source: EvidenceSimError,
    },
    /// Writing an output file failed.
    #[error("writing {path}: {source}")]
    Io {
        /// File.
        path: String,
        /// What failed.
        source: std::io::Error,
    },
}
