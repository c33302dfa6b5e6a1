//! The firmware's report: what it prints per map, call and streaming step, parsed.

/// One call's line of a report.
#[derive(Clone, Debug, PartialEq)]
pub struct Call {
    pub name: String,
    pub instructions: u64,
    pub stack: usize,
    /// `f32` bits of the value, or the error's text.
    pub value: Result<u32, String>,
}

/// One map's part of a report.
#[derive(Clone, Debug, PartialEq)]
pub struct MapReport {
    pub name: String,
    pub places: usize,
    pub classes: usize,
    pub calls: Vec<Call>,
    /// `f32` bits, one row per place.
    pub marginals: Vec<Vec<u32>>,
    pub mpe: Vec<u16>,
    /// The streaming state's calls: `set_all`, then one per step (named
    /// `observe_marginals` or `observe_marginal`), with the step's place.
    pub stream: Vec<(Call, Option<usize>)>,
    /// The state's marginals after the last step (`f32` bits, one row per place).
    pub state_marginals: Vec<Vec<u32>>,
    /// `STATE_BYTES` of the module (`state=` of the `map` line).
    pub state_bytes: Option<usize>,
    /// The state's full passes after the last step: `mpe`, `labelled_log_likelihood`.
    pub state_calls: Vec<Call>,
    /// The adversarial fusion sequence: per phase its last `observe_marginal` call.
    pub fusion: Vec<Call>,
    /// Per phase the state's log-likelihood and the place's marginal (`f32` bits).
    pub fusion_state: Vec<Vec<u32>>,
}

/// A parsed firmware report.
#[derive(Debug)]
pub struct Report {
    pub calibration: (u64, u64, u64),
    pub static_ram: usize,
    pub maps: Vec<MapReport>,
}

pub fn field<T: std::str::FromStr>(line: &str, key: &str) -> T {
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {key}= in report line {line:?}"))
}

/// A call record named `name`: `instructions=<n> stack=<b> value=<bits>|error=<e>`.
pub fn call(name: &str, line: &str) -> Call {
    let value = match line.split_once(" value=") {
        Some((_, v)) => Ok(u32::from_str_radix(v.trim(), 16).unwrap()),
        None => Err(line.split_once(" error=").map_or("?", |x| x.1).to_string()),
    };
    Call {
        name: name.to_string(),
        instructions: field(line, "instructions"),
        stack: field(line, "stack"),
        value,
    }
}

pub fn parse(text: &str) -> Report {
    let mut calibration = None;
    let mut static_ram = None;
    let mut maps: Vec<MapReport> = vec![];
    let mut done = false;
    for line in text.lines().map(str::trim_end) {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("calibration") => {
                calibration = Some((
                    field(line, "loop_instructions"),
                    field(line, "measured"),
                    field(line, "overhead"),
                ))
            }
            Some("ram") => static_ram = Some(field(line, "static")),
            Some("map") => maps.push(MapReport {
                name: words.next().unwrap().to_string(),
                places: field(line, "places"),
                classes: field(line, "classes"),
                calls: vec![],
                marginals: vec![],
                mpe: vec![],
                stream: vec![],
                state_marginals: vec![],
                state_bytes: line
                    .split_whitespace()
                    .find_map(|w| w.strip_prefix("state=")?.parse().ok()),
                state_calls: vec![],
                fusion: vec![],
                fusion_state: vec![],
            }),
            Some("fusion") => {
                let m = maps.last_mut().expect("a map line first");
                let phase: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(phase, m.fusion.len(), "fusion phases in order: {line}");
                m.fusion.push(call(words.next().unwrap_or("?"), line));
            }
            Some("fusion_state") => {
                let m = maps.last_mut().expect("a map line first");
                let phase: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(
                    phase,
                    m.fusion_state.len(),
                    "fusion states in order: {line}"
                );
                let bits = words.map(|w| u32::from_str_radix(w, 16));
                let bits: Result<Vec<u32>, _> = bits.collect();
                m.fusion_state
                    .push(bits.unwrap_or_else(|_| panic!("fusion state: {line}")));
            }
            Some("state_call") => {
                let call = call(words.next().unwrap(), line);
                let m = maps.last_mut().expect("a map line first");
                m.state_calls.push(call);
            }
            Some("call") => {
                let call = call(words.next().unwrap(), line);
                maps.last_mut().expect("a map line first").calls.push(call);
            }
            Some("stream") => {
                let call = call(words.next().unwrap(), line);
                maps.last_mut()
                    .expect("a map line first")
                    .stream
                    .push((call, None));
            }
            Some("step") => {
                let m = maps.last_mut().expect("a map line first");
                let i: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(i + 1, m.stream.len(), "steps in order, after set_all");
                let call = call(words.next().unwrap(), line);
                m.stream.push((call, Some(field(line, "place"))));
            }
            Some(tag @ ("marginals" | "state_marginals")) => {
                let m = maps.last_mut().expect("a map line first");
                let rows = if tag == "marginals" {
                    &mut m.marginals
                } else {
                    &mut m.state_marginals
                };
                let p: usize = words.next().unwrap().parse().unwrap();
                assert_eq!(p, rows.len(), "{tag} rows in order");
                rows.push(words.map(|w| u32::from_str_radix(w, 16).unwrap()).collect());
            }
            Some("mpe") => {
                maps.last_mut().expect("a map line first").mpe =
                    words.map(|w| w.parse().unwrap()).collect()
            }
            Some("done") => done = true,
            _ => {}
        }
    }
    assert!(done, "the report does not end with `done`:\n{text}");
    Report {
        calibration: calibration.expect("calibration line"),
        static_ram: static_ram.expect("ram line"),
        maps,
    }
}
