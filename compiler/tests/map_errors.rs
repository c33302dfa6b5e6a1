//! Bad input to the map constructor and loaders: every error names where.

use graphspn_compiler::map::{ClassSet, MapError, Place, TopoMap, cold};

fn good_line(id: i64, label: &str, nbrs: &[i64]) -> String {
    let mut cols = vec![
        id.to_string(),
        "0".into(),
        "1.5".into(),
        "-2.0".into(),
        "0".into(),
        "0".into(),
        "1.6".into(),
        "-2.4".into(),
        label.into(),
        "1152886490.9".into(),
    ];
    for k in 0..8 {
        let nb = nbrs.get(k).copied().unwrap_or(-1);
        cols.push(nb.to_string());
        cols.push(if nb == -1 {
            "-1.0".into()
        } else {
            "0.5".into()
        });
        cols.push(k.to_string());
    }
    cols.join(" ")
}

/// A sequence folder `<tmp>/Bldg/seq` with the given files.
fn seq(nodes: &str, rooms: Option<&str>) -> (tempfile::TempDir, std::path::PathBuf) {
    seq_in("Bldg", nodes, rooms)
}

/// A sequence folder `<tmp>/<building>/seq` with the given files.
fn seq_in(
    building: &str,
    nodes: &str,
    rooms: Option<&str>,
) -> (tempfile::TempDir, std::path::PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join(building).join("seq");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("nodes.dat"), nodes).unwrap();
    if let Some(r) = rooms {
        std::fs::write(dir.join("rooms.dat"), r).unwrap();
    }
    (tmp, dir)
}

fn three_nodes() -> Vec<String> {
    vec![
        good_line(0, "CR", &[1]),
        good_line(1, "DW", &[0, 2]),
        good_line(2, "1PO", &[1]),
    ]
}

const ROOMS3: &str = "0 1-CR-1\n1 1-DW-1\n2 1-1PO-2\n";

fn load_err(nodes: &str, rooms: Option<&str>) -> (MapError, String) {
    let (_tmp, dir) = seq(nodes, rooms);
    let e = cold::load_sequence(&dir).unwrap_err();
    let s = e.to_string();
    (e, s)
}

#[test]
fn good_small_sequence_loads() {
    let (_tmp, dir) = seq(&(three_nodes().join("\r\n") + "\r\n"), Some(ROOMS3));
    let m = cold::load_sequence(&dir).unwrap();
    assert_eq!(m.name, "Bldg/seq");
    assert_eq!(m.num_places(), 3);
    assert_eq!(m.num_edges(), 2, "0-1 listed both ways counts once");
    assert_eq!(m.place(1).class, Some(0));
    assert_eq!(
        (m.place(0).x, m.place(0).y),
        (1.5, -2.0),
        "pose = columns 2, 3"
    );
}

#[test]
fn un_nodes_isolated_nodes_and_small_components_dropped() {
    let lines = [
        good_line(0, "CR", &[1]),
        good_line(1, "CR", &[2]),
        good_line(2, "UN", &[3]), // unknown: dropped, so 3 becomes isolated
        good_line(3, "KT", &[]),
        good_line(4, "BA", &[5]), // a separate pair: smaller component
        good_line(5, "BA", &[]),
        good_line(6, "CR", &[0, 1]),
    ];
    let rooms = "0 1-CR-1\n1 1-CR-1\n2 1-UN-1\n3 1-KT-1\n4 1-BA-1\n5 1-BA-1\n6 1-CR-1\n";
    let (_tmp, dir) = seq(&lines.join("\n"), Some(rooms));
    let (m, dropped) = cold::load_sequence_report(&dir).unwrap();
    let ids: Vec<u32> = m.places().map(|p| p.id).collect();
    assert_eq!(ids, vec![0, 1, 6]);
    assert_eq!(m.num_edges(), 3);
    // What was dropped, and why, for the warnings of every command.
    assert_eq!(dropped.unknown, vec![2]);
    assert_eq!(dropped.isolated, vec![3]);
    assert_eq!(dropped.disconnected, vec![4, 5]);
    // The same through a building and a map set (`train`, `stats`, `evaluate`).
    let building = dir.parent().unwrap();
    let data = building.parent().unwrap();
    let loaded = cold::load_building_report(data, "Bldg").unwrap();
    assert_eq!(loaded[0].1, dropped);
    let set = graphspn_compiler::map::load_map_set_report(building).unwrap();
    assert_eq!(set.dropped, vec![dropped]);
}

/// The authors' relabelling of room `7-2PO-1` applies to Stockholm's maps only: a
/// room of that id in another building keeps its label.
#[test]
fn room_relabel_makes_1po_in_stockholm_only() {
    let lines = [good_line(0, "CR", &[1]), good_line(1, "2PO", &[0])];
    let rooms = "0 7-CR-1\n1 7-2PO-1\n";
    let (_tmp, dir) = seq_in("Stockholm", &lines.join("\n"), Some(rooms));
    let m = cold::load_sequence(&dir).unwrap();
    assert_eq!(m.place(1).class, Some(2), "1PO");
    let (_tmp, dir) = seq_in("MyLab", &lines.join("\n"), Some(rooms));
    let m = cold::load_sequence(&dir).unwrap();
    assert_eq!(m.place(1).class, Some(3), "2PO kept");
}

/// However a Stockholm sequence's path is written (relative to its building, or `.`
/// from inside it), the building is read from the path made absolute: the relabelling
/// applies alike. (A process-wide current folder: run in a child process.)
#[test]
fn room_relabel_reads_the_building_of_a_relative_path() {
    if std::env::var_os("GRAPHSPN_RELABEL_CHILD").is_some() {
        let dir = std::env::current_dir().unwrap();
        let m = cold::load_sequence(".").unwrap();
        assert_eq!(m.place(1).class, Some(2), "1PO through .");
        std::env::set_current_dir(dir.parent().unwrap()).unwrap();
        let m = cold::load_sequence("seq").unwrap();
        assert_eq!(m.place(1).class, Some(2), "1PO through seq");
        return;
    }
    let lines = [good_line(0, "CR", &[1]), good_line(1, "2PO", &[0])];
    let (_tmp, dir) = seq_in(
        "Stockholm",
        &lines.join("\n"),
        Some("0 7-CR-1\n1 7-2PO-1\n"),
    );
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "room_relabel_reads_the_building_of_a_relative_path",
            "--exact",
            "--nocapture",
        ])
        .env("GRAPHSPN_RELABEL_CHILD", "1")
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

/// A building's sub-folder that is not a sequence (no `nodes.dat`) is an error naming
/// it, as among a set of maps (it was skipped: `train` reported fewer maps without a
/// word); hidden folders and files are not read. `buildings_in` lists a data
/// folder's buildings, whatever their names.
#[test]
fn a_building_folder_without_nodes_dat_is_an_error_naming_it() {
    let lines = three_nodes();
    let (tmp, dir) = seq_in("MyLab", &lines.join("\n"), Some(ROOMS3));
    let building = dir.parent().unwrap();
    std::fs::create_dir(building.join(".cache")).unwrap();
    std::fs::write(building.join("notes.txt"), "not a map").unwrap();
    assert_eq!(cold::load_building(tmp.path(), "MyLab").unwrap().len(), 1);
    assert_eq!(cold::buildings_in(tmp.path()).unwrap(), vec!["MyLab"]);
    std::fs::create_dir(building.join("seq9")).unwrap();
    std::fs::write(building.join("seq9/rooms.dat"), ROOMS3).unwrap();
    let err = cold::load_building(tmp.path(), "MyLab").unwrap_err();
    assert!(matches!(err, MapError::NotASequence { .. }), "{err}");
    assert!(err.to_string().contains("seq9"), "{err}");
}

#[test]
fn missing_files() {
    let tmp = tempfile::tempdir().unwrap();
    let e = cold::load_sequence(tmp.path()).unwrap_err();
    assert!(matches!(e, MapError::MissingFile { .. }), "{e}");
    assert!(e.to_string().contains("nodes.dat"));
    let (e, s) = load_err(&three_nodes().join("\n"), None);
    assert!(matches!(e, MapError::MissingFile { .. }));
    assert!(
        s.contains("rooms.dat") && s.contains("no such file or folder"),
        "{s}"
    );
    assert!(TopoMap::load(tmp.path().join("nope.json")).is_err());
    let e = cold::load_building(tmp.path(), "Nowhere").unwrap_err();
    assert!(e.to_string().contains("Nowhere"), "{e}");
}

#[test]
fn wrong_column_count() {
    let mut l = three_nodes();
    l[1].push_str(" 7");
    let (e, s) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(
        matches!(
            e,
            MapError::ColumnCount {
                line: 2,
                found: 35,
                ..
            }
        ),
        "{s}"
    );
    assert!(s.contains("nodes.dat:2") && s.contains("34"), "{s}");
    let (e, s) = load_err(&three_nodes().join("\n"), Some("0 1-CR-1 x\n"));
    assert!(matches!(e, MapError::ColumnCount { line: 1, .. }), "{s}");
    assert!(s.contains("rooms.dat:1"), "{s}");
}

#[test]
fn malformed_numbers() {
    let mut l = three_nodes();
    l[2] = l[2].replacen("1.5", "1.5x", 1);
    let (e, s) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(
        matches!(
            e,
            MapError::BadNumber {
                line: 3,
                column: 2,
                ..
            }
        ),
        "{s}"
    );
    assert!(
        s.contains("nodes.dat:3") && s.contains("column 2: \"1.5x\" is not a finite number"),
        "{s}"
    );
    let mut l = three_nodes();
    l[0] = l[0].replacen("0 0 ", "0 2 ", 1);
    let (e, s) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(
        matches!(
            e,
            MapError::BadNumber {
                line: 1,
                column: 1,
                ..
            }
        ),
        "{s}"
    );
    assert!(
        s.contains("column 1: \"2\" is not 0 or 1 (the placeholder flag)"),
        "{s}"
    );
    // A neighbour is an integer id.
    let mut l = three_nodes();
    l[0] = good_line(0, "CR", &[1]).replacen(" 1 0.5 0", " 1.0 0.5 0", 1);
    let (_, s) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(s.contains("column 10: \"1.0\" is not an integer"), "{s}");
    let mut l = three_nodes();
    l[0] = l[0].replacen("0 0 ", "abc 0 ", 1);
    let (e, _) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(matches!(
        e,
        MapError::BadNumber {
            line: 1,
            column: 0,
            ..
        }
    ));
    let mut l = three_nodes();
    l[0] = l[0].replacen("0 0 1.5", "0 0 NaN", 1);
    let (e, _) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(
        matches!(e, MapError::BadNumber { column: 2, .. }),
        "NaN pose rejected"
    );
}

#[test]
fn unknown_raw_label() {
    let mut l = three_nodes();
    l[1] = good_line(1, "XYZ", &[0, 2]);
    let (e, s) = load_err(&l.join("\n"), Some("0 1-CR-1\n1 1-XYZ-1\n2 1-1PO-2\n"));
    assert!(
        matches!(
            e,
            MapError::UnknownLabel {
                line: 2,
                column: 8,
                ..
            }
        ),
        "{s}"
    );
    assert!(s.contains("XYZ") && s.contains("nodes.dat:2"), "{s}");
}

#[test]
fn edge_to_missing_node() {
    let mut l = three_nodes();
    l[2] = good_line(2, "1PO", &[1, 9]);
    let (e, s) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(
        matches!(
            e,
            MapError::MissingNeighbor {
                line: 3,
                node: 2,
                neighbor: 9,
                ..
            }
        ),
        "{s}"
    );
    assert!(s.contains("neighbour 9"), "{s}");
}

#[test]
fn duplicate_ids() {
    let mut l = three_nodes();
    l.push(good_line(1, "DW", &[0]));
    let (e, s) = load_err(&l.join("\n"), Some(ROOMS3));
    assert!(
        matches!(
            e,
            MapError::DuplicateNodeLine {
                line: 4,
                first_line: 2,
                id: 1,
                ..
            }
        ),
        "{s}"
    );
    let (e, _) = load_err(&three_nodes().join("\n"), Some("0 1-CR-1\n0 1-CR-1\n"));
    assert!(matches!(e, MapError::DuplicateNodeLine { id: 0, .. }));
}

#[test]
fn room_problems() {
    let (e, s) = load_err(&three_nodes().join("\n"), Some("0 1-CR-1\n1 1-DW-1\n"));
    assert!(matches!(e, MapError::MissingRoom { node: 2, .. }), "{s}");
    assert!(
        s.contains("no room for node 2") && s.contains("nodes.dat:3"),
        "{s}"
    );
    let (e, s) = load_err(
        &three_nodes().join("\n"),
        Some("0 1-CR-1\n1 1-KT-1\n2 1-1PO-2\n"),
    );
    assert!(
        matches!(e, MapError::RoomLabelMismatch { node: 1, .. }),
        "{s}"
    );
    let (e, s) = load_err(
        &three_nodes().join("\n"),
        Some("0 CR\n1 1-DW-1\n2 1-1PO-2\n"),
    );
    assert!(matches!(e, MapError::BadRoomId { line: 1, .. }), "{s}");
}

#[test]
fn everything_unknown_is_an_error() {
    let l = [good_line(0, "UN", &[1]), good_line(1, "UN", &[0])];
    let (e, _) = load_err(&l.join("\n"), Some("0 1-UN-1\n1 1-UN-1\n"));
    assert!(matches!(e, MapError::EmptyAfterFiltering { .. }));
}

fn place(id: u32) -> Place {
    Place {
        id,
        class: Some(1),
        placeholder: false,
        x: id as f64,
        y: 0.0,
    }
}

#[test]
fn constructor_errors() {
    let c = ClassSet::paper;
    let e = TopoMap::new("m", c(), vec![place(1), place(1)], vec![]).unwrap_err();
    assert!(matches!(e, MapError::DuplicatePlace { id: 1 }), "{e}");
    let e = TopoMap::new("m", c(), vec![place(1), place(2)], vec![(2, 2)]).unwrap_err();
    assert!(matches!(e, MapError::SelfLoop { id: 2 }), "{e}");
    let e = TopoMap::new("m", c(), vec![place(1), place(2)], vec![(1, 7)]).unwrap_err();
    assert!(
        matches!(e, MapError::MissingEndpoint { missing: 7, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("place 7"));
    let mut p = place(3);
    p.class = Some(10);
    let e = TopoMap::new("m", c(), vec![p], vec![]).unwrap_err();
    assert!(matches!(e, MapError::ClassOutOfRange { id: 3, .. }), "{e}");
    let mut p = place(4);
    p.y = f64::INFINITY;
    let e = TopoMap::new("m", c(), vec![p], vec![]).unwrap_err();
    assert!(matches!(e, MapError::NonFinitePose { id: 4, .. }), "{e}");
}

fn json_err(text: &str) -> String {
    TopoMap::from_json(text).unwrap_err().to_string()
}

#[test]
fn json_errors() {
    let s = json_err("{\n  \"format\": 1,\n  \"name\": oops\n}");
    assert!(s.contains("line 3"), "{s}");
    let s = json_err(r#"{"format": 2, "name": "m", "classes": ["A"], "places": [], "edges": []}"#);
    assert!(s.contains("format 2"), "{s}");
    let s = json_err(
        r#"{"format": 1, "name": "m", "classes": ["A"], "places": [{"id": 5, "class": "B", "placeholder": false, "x": 0, "y": 0}], "edges": []}"#,
    );
    assert!(s.contains("place 5") && s.contains("\"B\""), "{s}");
    let s = json_err(
        r#"{"format": 1, "name": "m", "classes": ["A"], "places": [{"id": 5, "class": null, "placeholder": false, "x": 0, "y": 0}], "edges": [[5, 6]]}"#,
    );
    assert!(s.contains("place 6"), "{s}");
    let s =
        json_err(r#"{"format": 1, "name": "m", "classes": ["A", "A"], "places": [], "edges": []}"#);
    assert!(s.contains("twice"), "{s}");
    let s = json_err(
        r#"{"format": 1, "name": "m", "classes": ["A"], "places": [], "edges": [], "extra": 1}"#,
    );
    assert!(s.contains("extra"), "{s}");
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("bad.json");
    std::fs::write(&p, "{").unwrap();
    let s = TopoMap::load(&p).unwrap_err().to_string();
    assert!(s.contains("bad.json") && s.contains("line 1"), "{s}");
}

/// A folder of maps holding a sub-folder that is not a COLD sequence (no `nodes.dat`):
/// an error naming that sub-folder (it was skipped without a word); files that are not
/// maps are returned for a warning; hidden entries are skipped (issue 23 §3).
#[test]
fn a_folder_among_the_maps_without_nodes_dat_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let floor =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../generated/demo/floor.json");
    std::fs::copy(&floor, dir.path().join("a.json")).unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not a map").unwrap();
    std::fs::create_dir(dir.path().join(".cache")).unwrap();
    let set = graphspn_compiler::map::load_map_set_report(dir.path()).unwrap();
    assert_eq!(set.maps.len(), 1);
    assert_eq!(set.not_read, vec![dir.path().join("notes.txt")]);
    std::fs::create_dir(dir.path().join("b_sequence")).unwrap();
    let err = graphspn_compiler::map::load_map_set(dir.path()).unwrap_err();
    assert!(matches!(err, MapError::NotASequence { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("b_sequence") && msg.contains("nodes.dat"),
        "{msg}"
    );
}

/// Two files of one folder that hold maps of the same name: refused, naming both
/// files (results are kept per map name, so `evaluate` merged them into one map).
#[test]
fn two_maps_of_one_name_in_a_set_are_an_error_naming_both_files() {
    let dir = tempfile::tempdir().unwrap();
    let floor =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../generated/demo/floor.json");
    std::fs::copy(&floor, dir.path().join("a.json")).unwrap();
    std::fs::copy(&floor, dir.path().join("b.json")).unwrap();
    let err = graphspn_compiler::map::load_map_set(dir.path()).unwrap_err();
    assert!(matches!(err, MapError::DuplicateMapName { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("a.json") && msg.contains("b.json") && msg.contains("n80_seed1"),
        "{msg}"
    );
}
