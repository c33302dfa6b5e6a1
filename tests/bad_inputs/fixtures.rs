//! The corpus's fixtures: the binary, the folder snapshot, the case record and the
//! demo inputs every section edits.

use super::*;

pub fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// The binary, with no data variable (the shipped maps are found by default).
pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_graphspn"));
    c.env_remove("GRAPHSPN_DATA").env("RUST_BACKTRACE", "0");
    c
}

/// Every file under `dir` with its content and modification time.
pub fn snapshot(dir: &Path) -> BTreeMap<PathBuf, (Vec<u8>, std::time::SystemTime)> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.insert(p.clone(), (Vec::new(), std::time::UNIX_EPOCH));
                stack.push(p);
            } else {
                let m = std::fs::metadata(&p).unwrap().modified().unwrap();
                out.insert(p.clone(), (std::fs::read(&p).unwrap(), m));
            }
        }
    }
    out
}

/// One malformed input: arguments (`{root}` stands for the fixture folder), the exit
/// status expected and fragments the error message must hold.
pub struct Case {
    pub name: String,
    pub args: Vec<String>,
    pub code: i32,
    pub expect: Vec<String>,
}

pub fn case(name: &str, args: &[&str], code: i32, expect: &[&str]) -> Case {
    Case {
        name: name.to_string(),
        args: args.iter().map(|s| s.to_string()).collect(),
        code,
        expect: expect.iter().map(|s| s.to_string()).collect(),
    }
}

pub fn write_json(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap() + "\n").unwrap();
}

pub fn demo_model() -> Value {
    serde_json::from_str(&std::fs::read_to_string(repo("generated/demo/model.json")).unwrap())
        .unwrap()
}

pub fn leaf(var: u32, class: u32) -> Value {
    json!({"kind": "leaf", "var": var, "class": class})
}

/// A small valid SPN for the two-node `pair` template: two 10-class sums under a product.
/// Nodes 0-9: var 0 leaves; 10-19: var 1 leaves; 20, 21: sums; 22: product (root).
pub fn tiny_pair() -> Value {
    let mut nodes: Vec<Value> = Vec::new();
    for v in 0..2 {
        for k in 0..10 {
            nodes.push(leaf(v, k));
        }
    }
    for v in 0..2u32 {
        let children: Vec<u32> = (v * 10..v * 10 + 10).collect();
        nodes.push(json!({"kind": "sum", "children": children, "weights": vec![0.1; 10]}));
    }
    nodes.push(json!({"kind": "product", "children": [20, 21]}));
    json!({"classes": [10, 10], "nodes": nodes, "root": 22})
}

/// Model mutations: (file stem, what to do to the demo model, message fragments).
pub type Mutation = (&'static str, fn(&mut Value), &'static [&'static str]);

/// The decompositions file of the demo floor written by `graphspn decompose`.
pub fn demo_decompositions(root: &Path) -> Value {
    let out = root.join("decs.json");
    assert!(
        bin()
            .args(["decompose", "--count", "2", "--model"])
            .arg(root.join("model.json"))
            .arg("--map")
            .arg(root.join("floor.json"))
            .arg("--out")
            .arg(&out)
            .status()
            .unwrap()
            .success()
    );
    serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap()
}

/// A COLD sequence copied from the shipped Freiburg/seq1_cloudy1, with `edit` applied
/// to the lines of its nodes.dat and rooms.dat.
pub fn cold_copy(dir: &Path, edit: impl Fn(&mut Vec<String>, &mut Vec<String>)) {
    let src = repo("data/cold-topomaps/Freiburg/seq1_cloudy1");
    let lines = |f: &str| -> Vec<String> {
        std::fs::read_to_string(src.join(f))
            .unwrap()
            .lines()
            .map(String::from)
            .collect()
    };
    let (mut nodes, mut rooms) = (lines("nodes.dat"), lines("rooms.dat"));
    edit(&mut nodes, &mut rooms);
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("nodes.dat"), nodes.join("\n") + "\n").unwrap();
    std::fs::write(dir.join("rooms.dat"), rooms.join("\n") + "\n").unwrap();
}

pub fn set_col(line: &mut String, col: usize, value: &str) {
    let mut cols: Vec<&str> = line.split_whitespace().collect();
    cols[col] = value;
    *line = cols.join(" ");
}

/// One `nodes.dat` line: id, not a placeholder, pose (x, 0), label, neighbours.
pub fn cold_line(id: u32, x: f64, label: &str, nbs: &[u32]) -> String {
    let mut cols = vec![
        id.to_string(),
        "0".into(),
        x.to_string(),
        "0".into(),
        "0".into(),
        "0".into(),
        x.to_string(),
        "0".into(),
        label.into(),
        "1.0".into(),
    ];
    for t in 0..8 {
        match nbs.get(t) {
            Some(n) => cols.extend([n.to_string(), "0.5".into(), "0".into()]),
            None => cols.extend(["-1".into(), "-1.0".into(), "0".into()]),
        }
    }
    cols.join(" ")
}
