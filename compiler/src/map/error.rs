//! Errors of map construction and of the map loaders.

use std::path::PathBuf;

use super::PlaceId;

/// Why a map could not be built or loaded. Every message says where: the file,
/// line and column, or the place id concerned.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// A required file or folder does not exist.
    #[error("{}: no such file or folder", path.display())]
    MissingFile {
        /// The file looked for.
        path: PathBuf,
    },
    /// Any other I/O failure.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A line of a `.dat` file has the wrong number of columns.
    #[error("{}:{line}: expected {expected} columns, found {found}", path.display())]
    ColumnCount {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Columns required.
        expected: usize,
        /// Columns present.
        found: usize,
    },
    /// A column that must hold a number does not (or not one of the kind it needs).
    #[error("{}:{line}: column {column}: {text:?} is not {expected}", path.display())]
    BadNumber {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// 0-based column index (as in `docs/FORMATS.md`).
        column: usize,
        /// The offending text.
        text: String,
        /// What the column holds, e.g. `an integer`, `0 or 1 (the placeholder flag)`.
        expected: &'static str,
    },
    /// A raw place label that the class table does not know.
    #[error("{}:{line}: column {column}: unknown raw label {label:?}", path.display())]
    UnknownLabel {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// 0-based column index.
        column: usize,
        /// The label.
        label: String,
    },
    /// A neighbour listing names a node that the file does not define.
    #[error("{}:{line}: node {node} lists neighbour {neighbor}, which does not exist", path.display())]
    MissingNeighbor {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the listing node.
        line: usize,
        /// The listing node.
        node: i64,
        /// The missing neighbour id.
        neighbor: i64,
    },
    /// A node id defined twice in a file.
    #[error("{}:{line}: node id {id} defined twice (first on line {first_line})", path.display())]
    DuplicateNodeLine {
        /// The file.
        path: PathBuf,
        /// 1-based line of the second definition.
        line: usize,
        /// 1-based line of the first definition.
        first_line: usize,
        /// The id.
        id: i64,
    },
    /// A node id outside the range of place ids (`0..=u32::MAX`).
    #[error("{}:{line}: node id {id} is not a valid place id (0..=4294967295)", path.display())]
    BadNodeId {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The id.
        id: i64,
    },
    /// A room id that is not `floor-LABEL-k`.
    #[error("{}:{line}: malformed room id {room:?} (expected floor-LABEL-k)", path.display())]
    BadRoomId {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The room id.
        room: String,
    },
    /// `rooms.dat` has no entry for a node of `nodes.dat`.
    #[error("{}: no room for node {node} ({}:{nodes_line}); every node needs a `node_id room_id` line", path.display(), nodes_path.display())]
    MissingRoom {
        /// The `rooms.dat` file.
        path: PathBuf,
        /// The node id.
        node: i64,
        /// The `nodes.dat` file.
        nodes_path: PathBuf,
        /// The node's line in `nodes.dat` (1-based).
        nodes_line: usize,
    },
    /// `rooms.dat` names a node that `nodes.dat` does not have.
    #[error("{}:{line}: node {node} is not in nodes.dat", path.display())]
    StrayRoom {
        /// The `rooms.dat` file.
        path: PathBuf,
        /// Line number (1-based).
        line: usize,
        /// The node id.
        node: i64,
    },
    /// The label of a node's room in `rooms.dat` differs from its label in `nodes.dat`.
    #[error(
        "{}:{line}: node {node} has label {label:?} but its room {room:?} says otherwise",
        path.display()
    )]
    RoomLabelMismatch {
        /// The `nodes.dat` file.
        path: PathBuf,
        /// 1-based line in `nodes.dat`.
        line: usize,
        /// The node id.
        node: i64,
        /// Label from `nodes.dat` column 8.
        label: String,
        /// Room id from `rooms.dat`.
        room: String,
    },
    /// Nothing is left of a map after filtering.
    #[error("{}: no place left after dropping unknown and isolated nodes", path.display())]
    EmptyAfterFiltering {
        /// The sequence folder.
        path: PathBuf,
    },
    /// A building folder without sequences.
    #[error("{}: no sequence folders (with nodes.dat) found", path.display())]
    NoSequences {
        /// The building folder.
        path: PathBuf,
    },
    /// A folder given as a set of maps holds no map.
    #[error("{}: holds no map (expected JSON map files or COLD sequence folders with nodes.dat)", path.display())]
    NoMaps {
        /// The folder.
        path: PathBuf,
    },
    /// A sub-folder of a folder of maps that is not a COLD sequence.
    #[error("{}: not a map: every folder among the maps (or of a building) must be a COLD sequence holding nodes.dat and rooms.dat; move it out", path.display())]
    NotASequence {
        /// The sub-folder.
        path: PathBuf,
    },
    /// Two maps of one set carry the same name (results are kept per map name, so
    /// they would be merged into one).
    #[error("{} and {}: both maps are named {name:?}; a map set needs one name per map (rename one in its file)", first.display(), second.display())]
    DuplicateMapName {
        /// The name.
        name: String,
        /// The first file or folder with it.
        first: PathBuf,
        /// The second.
        second: PathBuf,
    },
    /// Two places share an id.
    #[error("place id {id} appears twice")]
    DuplicatePlace {
        /// The id.
        id: PlaceId,
    },
    /// An edge joins a place to itself.
    #[error("edge joins place {id} to itself")]
    SelfLoop {
        /// The place id.
        id: PlaceId,
    },
    /// An edge endpoint names no place of the map.
    #[error("edge ({a}, {b}) names place {missing}, which does not exist")]
    MissingEndpoint {
        /// First endpoint.
        a: PlaceId,
        /// Second endpoint.
        b: PlaceId,
        /// The missing one.
        missing: PlaceId,
    },
    /// A place's class index is out of range of the class set.
    #[error("place {id} has class index {class}, but there are only {num_classes} classes")]
    ClassOutOfRange {
        /// The place id.
        id: PlaceId,
        /// The class index.
        class: u16,
        /// Number of classes.
        num_classes: usize,
    },
    /// A pose coordinate is NaN or infinite.
    #[error("place {id} has a non-finite pose ({x}, {y})")]
    NonFinitePose {
        /// The place id.
        id: PlaceId,
        /// Pose x.
        x: f64,
        /// Pose y.
        y: f64,
    },
    /// [`crate::map::TopoMap::add_place`] got an id not above every existing id
    /// (place order must stay sorted by id).
    #[error("new place id {id} must exceed the largest existing id {max}")]
    PlaceIdNotIncreasing {
        /// The new id.
        id: PlaceId,
        /// The largest existing id.
        max: PlaceId,
    },
    /// An invalid class set.
    #[error("invalid class set: {0}")]
    Classes(String),
    /// A place names a class the map's class set lacks.
    #[error("place {id} has class {class:?}, which is not among the map's classes")]
    UnknownClass {
        /// The place id.
        id: PlaceId,
        /// The class name.
        class: String,
    },
    /// Malformed JSON, or JSON not matching the map format.
    #[error("line {line}, column {column}: {message}")]
    Json {
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What serde_json reported.
        message: String,
    },
    /// A map with more places than the caller can take (counted in the file, before
    /// the map's graph is built).
    #[error("{}: {places} places, more than the {limit} allowed", path.display())]
    TooManyPlaces {
        /// The map file (`nodes.dat` of a COLD map).
        path: PathBuf,
        /// Places the file lists (for a COLD map: the lines of `nodes.dat`, before
        /// filtering).
        places: usize,
        /// The limit.
        limit: usize,
    },
    /// A JSON map of an unsupported format version.
    #[error("unsupported map format {found} (this version reads format {supported})")]
    FormatVersion {
        /// Version in the file.
        found: u64,
        /// The version this build reads.
        supported: u64,
    },
    /// Invalid synthetic generator parameters.
    #[error("invalid synthetic map parameters: {0}")]
    SyntheticParams(String),
    /// An error inside a file (the source says what and where inside it).
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// The error.
        #[source]
        source: Box<MapError>,
    },
}

impl MapError {
    /// Attach the file an error happened in (for errors that do not name it yet).
    pub fn in_file(self, path: impl Into<PathBuf>) -> MapError {
        MapError::InFile {
            path: path.into(),
            source: Box::new(self),
        }
    }

    /// Map an I/O error on `path`, turning "not found" into [`MapError::MissingFile`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> MapError {
        let path = path.into();
        if source.kind() == std::io::ErrorKind::NotFound {
            MapError::MissingFile { path }
        } else {
            MapError::Io { path, source }
        }
    }
}

/// Why a model cannot label a map: the one check of every model family
/// ([`TopoMap::check_labellable`](super::TopoMap::check_labellable)).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapFitError {
    /// The map's class names (in order) are not the model's.
    #[error(
        "the map {map:?} has classes {} but the model has {}",
        super::shown_class_names(map_classes),
        super::shown_class_names(model_classes)
    )]
    ClassMismatch {
        /// Map name.
        map: String,
        /// Class names of the map.
        map_classes: Vec<String>,
        /// Class names of the model.
        model_classes: Vec<String>,
    },
    /// The map has no places.
    #[error("the map {0:?} has no places")]
    Empty(String),
    /// The map's graph breaks an invariant (e.g. a self-loop added after
    /// [`TopoMap::new`](super::TopoMap::new) checked it).
    #[error("the map {map:?} is malformed: {what}")]
    Malformed {
        /// Map name.
        map: String,
        /// What breaks.
        what: String,
    },
}
