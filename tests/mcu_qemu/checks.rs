//! Every number of a report checked: against the host build, the interpreter, the
//! tree reference, the fixed-point bounds and the streaming references.

use super::*;

/// Answers of the in-process host build (`graphspn-generated`) of one map.
pub struct HostAnswers {
    pub values: [Result<f32, String>; 4],
    pub marginals: Vec<Vec<f32>>,
    pub mpe: Vec<u16>,
}

/// The firmware's evidence and labels for map `index` (see `firmware/src/evidence.rs`).
pub fn inputs(index: u64, places: usize, classes: usize, unknown: u16) -> (Vec<f32>, Vec<u16>) {
    let mut rows = vec![0.0f32; places * classes];
    let mut labels = vec![0u16; places];
    evidence::fill(
        evidence::SEED + index,
        classes,
        &mut rows,
        &mut labels,
        unknown,
    );
    (rows, labels)
}

macro_rules! host_answers {
    ($m:ident, $index:expr) => {{
        let (rows, labels) = inputs($index, $m::NUM_PLACES, $m::NUM_CLASSES, $m::UNKNOWN);
        let mut e: $m::Evidence = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        e.as_flattened_mut().copy_from_slice(&rows);
        let l: $m::Labels = labels.try_into().unwrap();
        let mut marg: $m::Marginals = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        let mut mpe: $m::Labels = [0; $m::NUM_PLACES];
        let s = |r: Result<f32, graphspn::runtime::EvidenceError>| r.map_err(|e| format!("{e:?}"));
        let values = [
            s($m::log_likelihood(&e)),
            s($m::marginals(&e, &mut marg)),
            s($m::mpe(&e, &mut mpe)),
            s($m::labelled_log_likelihood(&l, &e)),
        ];
        HostAnswers {
            values,
            marginals: marg.iter().map(|r| r.to_vec()).collect(),
            mpe: mpe.to_vec(),
        }
    }};
}

pub fn close(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= TOL * b.abs().max(1.0)
}

pub fn map_file(name: &str) -> &'static str {
    match name.trim_end_matches("_trees") {
        "demo_floor" => "floor.json",
        "saarbrucken_seq2_night1" => "saarbrucken_seq2_night1.json",
        _ => panic!("unknown map {name}"),
    }
}

/// The tree mixture's reference (`TreeInstance`) of firmware module `name` with
/// evidence `rows` (`f32` rows, widened).
pub fn tree_reference(name: &str, rows: &[Vec<f32>]) -> TreeInstance {
    let AnyInputs::TreeMixture(i) = firmware_builder(name).load_any().unwrap() else {
        panic!("{name} is not a tree mixture");
    };
    let mut inst = TreeInstance::build(&i.model, &i.map, i.trees).unwrap();
    let wide: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| r.iter().map(|&x| f64::from(x)).collect())
        .collect();
    inst.set_all_evidence(&wide).unwrap();
    inst
}

/// The value call `i` of map `m` returned (panics naming the call on an error).
pub fn call_value(target: &str, m: &MapReport, i: usize) -> f64 {
    let call = &m.calls[i];
    f64::from(f32::from_bits(*call.value.as_ref().unwrap_or_else(|e| {
        panic!("{target} {} {}: error {e}", m.name, call.name)
    })))
}

/// The largest absolute difference between the firmware's marginals (`f32` bits) and
/// a reference's.
pub fn largest_marginal_error(got: &[Vec<u32>], want: &[Vec<f64>]) -> f64 {
    got.iter()
        .flatten()
        .zip(want.iter().flatten())
        .map(|(&g, &w)| (f64::from(f32::from_bits(g)) - w).abs())
        .fold(0.0, f64::max)
}

/// [`check_map`] for a tree-mixture module: every call against `TreeInstance` (the
/// interpreter's instance SPN is checked against it in `generated_trees.rs`).
pub fn check_tree_map(target: &str, m: &MapReport, index: u64) {
    let (n, c) = (m.places, m.classes);
    let (rows, labels) = inputs(index, n, c, u16::MAX);
    let rows: Vec<Vec<f32>> = rows.chunks(c).map(<[f32]>::to_vec).collect();
    let inst = tree_reference(&m.name, &rows);
    let ctx = |what: &str| format!("{target} {} {what}", m.name);
    let value = |i: usize| call_value(target, m, i);
    let want = inst.marginals().unwrap();
    let best = inst.mpe(&vec![None; n]).unwrap().log_max_product;
    if is_fixed(target) {
        // Fixed-point messages: each entry within η of itself, so the log-likelihood
        // within n·η, a marginal within 4n·η, beside f32's roundings (TOL).
        let b = firmware_builder(&m.name).arithmetic(Arithmetic::Fixed);
        let (_, report) = b.report_from_any(&b.load_any().unwrap()).unwrap();
        let eta = report
            .message_error
            .expect("the demo tree model gets fixed-point messages");
        let (ll_bound, marginal_bound) = (TOL + n as f64 * eta, TOL + 4.0 * n as f64 * eta);
        let ll_err = (value(0) - want.mixed.log_likelihood).abs();
        let marginal_err = largest_marginal_error(&m.marginals, &want.mixed.probs);
        // mpe: max-product messages in fixed point too, its value within n·η.
        let mpe_err = (value(2) - best).abs();
        eprintln!(
            "{target} {}: fixed-point messages (η = {eta:.2e}), largest errors against TreeInstance: log-likelihood {ll_err:.2e} (bound {ll_bound:.2e}), marginals {marginal_err:.2e} (bound {marginal_bound:.2e}), mpe value {mpe_err:.2e} (bound {ll_bound:.2e})",
            m.name
        );
        assert!(
            ll_err <= ll_bound && marginal_err <= marginal_bound && mpe_err <= ll_bound,
            "{}",
            ctx("fixed-point error bound")
        );
    }
    for i in [0, 1] {
        let w = want.mixed.log_likelihood;
        assert!(close(value(i), w), "{}: {} vs {w}", ctx("ll"), value(i));
    }
    for (p, row) in m.marginals.iter().enumerate() {
        for (k, &bits) in row.iter().enumerate() {
            let (got, w) = (f64::from(f32::from_bits(bits)), want.mixed.probs[p][k]);
            assert!(
                (got - w).abs() <= TOL,
                "{}: {p}/{k}: {got} vs {w}",
                ctx("marginals")
            );
        }
    }
    assert!(
        close(value(2), best),
        "{}: {} vs {best}",
        ctx("mpe"),
        value(2)
    );
    let fixed: Vec<Option<u16>> = m.mpe.iter().map(|&l| Some(l)).collect();
    let attained = inst.mpe(&fixed).unwrap().log_max_product;
    assert!(
        close(attained, best),
        "{}: labels attain {attained}",
        ctx("mpe")
    );
    let probe: Vec<Option<u16>> = labels
        .iter()
        .map(|&l| (l != u16::MAX).then_some(l))
        .collect();
    let want_l = inst.log_likelihood_labelled(&probe).unwrap();
    assert!(
        close(value(3), want_l),
        "{}: {} vs {want_l}",
        ctx("labelled"),
        value(3)
    );
}

/// Whether `Builder` gives `target` the fixed-point kernel (no FPU).
pub fn is_fixed(target: &str) -> bool {
    Arithmetic::for_target(target) == Arithmetic::Fixed
}

/// Checks one map of an MCU report against the interpreter (tolerances) and returns
/// how many of its numbers differ in bits from `host` (the x86-64-v3 build). On a
/// fixed-point target it also prints the largest errors and checks them against the
/// kernel's documented bound (`fixed_bounds`).
pub fn check_map(target: &str, m: &MapReport, index: u64, host: &HostAnswers) -> usize {
    if m.name.ends_with("_trees") {
        check_tree_map(target, m, index);
        return compare_with_host(target, m, host);
    }
    let demo = root().join("generated/demo");
    let inputs_ = Builder::new(demo.join("model.json"), demo.join(map_file(&m.name)))
        .seed(0)
        .count(5)
        .load()
        .unwrap();
    let inst = Instance::build(&inputs_.model, &inputs_.map, inputs_.decompositions).unwrap();
    let mut ev = Evaluator::new(&inst.spn).unwrap();
    let (n, c) = (m.places, m.classes);
    let unknown = u16::MAX;
    let (rows, labels) = inputs(index, n, c, unknown);
    let evidence = Evidence::from_rows(
        rows.chunks(c)
            .map(|r| r.iter().map(|&x| f64::from(x)).collect())
            .collect(),
    );
    let free = vec![None; n];
    let ctx = |what: &str| format!("{target} {} {what}", m.name);
    let value = |i: usize| call_value(target, m, i);
    let names: Vec<&str> = m.calls.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "log_likelihood",
            "marginals",
            "mpe",
            "labelled_log_likelihood"
        ],
        "{}",
        ctx("calls")
    );
    // Interpreter.
    let want = ev.marginals(&free, &evidence).unwrap();
    if is_fixed(target) {
        let (ll_bound, marginal_bound) = fixed_bounds(&inst);
        let ll_err = (value(1) - want.log_likelihood).abs();
        let marginal_err = largest_marginal_error(&m.marginals, &want.probs);
        eprintln!(
            "{target} {}: fixed-point kernel, largest errors against the interpreter: log-likelihood {ll_err:.2e} (bound {ll_bound:.2e}), marginals {marginal_err:.2e} (bound {marginal_bound:.2e})",
            m.name
        );
        assert!(
            ll_err <= ll_bound && marginal_err <= marginal_bound,
            "{}",
            ctx("fixed-point error bound")
        );
    }
    for i in [0, 1] {
        assert!(
            close(value(i), want.log_likelihood),
            "{}: {} vs interpreter {}",
            ctx(names[i]),
            value(i),
            want.log_likelihood
        );
    }
    for (p, row) in m.marginals.iter().enumerate() {
        for (k, &bits) in row.iter().enumerate() {
            let got = f64::from(f32::from_bits(bits));
            assert!(
                (got - want.probs[p][k]).abs() <= TOL,
                "{}: place {p} class {k}: {got} vs interpreter {}",
                ctx("marginals"),
                want.probs[p][k]
            );
        }
    }
    let best = ev.log_max_product(&free, &evidence).unwrap();
    assert!(
        close(value(2), best),
        "{}: {} vs interpreter {best}",
        ctx("mpe"),
        value(2)
    );
    let fixed: Vec<Option<u32>> = m.mpe.iter().map(|&l| Some(u32::from(l))).collect();
    let attained = ev.log_max_product(&fixed, &evidence).unwrap();
    assert!(
        close(attained, best),
        "{}: labels attain {attained} not {best}",
        ctx("mpe")
    );
    let probe: Vec<Option<u32>> = labels
        .iter()
        .map(|&l| (l != unknown).then_some(u32::from(l)))
        .collect();
    let want_l = ev.log_likelihood(&probe, &evidence).unwrap();
    assert!(
        close(value(3), want_l),
        "{}: {} vs interpreter {want_l}",
        ctx("labelled_log_likelihood"),
        value(3)
    );
    // The x86-64-v3 host build: same tolerances, and count differing bits.
    compare_with_host(target, m, host)
}

/// The fixed-point kernel's documented error bound for an instance (see the
/// generator's `codegen::fixed` module): each template value off by at most `2^-13` of
/// itself and each local posterior by `2^-10`, so with `K` components in the largest
/// decomposition the log-likelihood is off by at most `K·2^-13` (plus `f32` rounding
/// of the sum, 1e-3 here) and a marginal by `2^-10 + 2K·2^-13` (the decomposition
/// weights' relative error).
pub fn fixed_bounds(inst: &Instance) -> (f64, f64) {
    let k = inst
        .decompositions
        .iter()
        .map(|d| d.components.len())
        .max()
        .unwrap_or(0) as f64;
    let unit = 2f64.powi(-13);
    (k * unit + 1e-3, 8.0 * unit + 2.0 * k * unit)
}

/// How many of a map's numbers differ in bits from the x86-64-v3 host build `host`
/// (all within the tolerances).
pub fn compare_with_host(target: &str, m: &MapReport, host: &HostAnswers) -> usize {
    let ctx = |what: &str| format!("{target} {} {what}", m.name);
    let names = [
        "log_likelihood",
        "marginals",
        "mpe",
        "labelled_log_likelihood",
    ];
    let value = |i: usize| f64::from(f32::from_bits(*m.calls[i].value.as_ref().unwrap()));
    let mut differ = 0;
    for (i, h) in host.values.iter().enumerate() {
        let h = h
            .as_ref()
            .unwrap_or_else(|e| panic!("host {}: {e}", ctx(names[i])));
        assert!(
            close(value(i), f64::from(*h)),
            "{}: {} vs host {h}",
            ctx(names[i]),
            value(i)
        );
        differ += usize::from(m.calls[i].value != Ok(h.to_bits()));
    }
    for (got, h) in m
        .marginals
        .iter()
        .flatten()
        .zip(host.marginals.iter().flatten())
    {
        assert!((f64::from(f32::from_bits(*got)) - f64::from(*h)).abs() <= TOL);
        differ += usize::from(*got != h.to_bits());
    }
    differ += m.mpe.iter().zip(&host.mpe).filter(|(a, b)| a != b).count();
    differ
}

/// One map's results: everything but instruction counts and stack, which must
/// agree bit for bit between builds of the same code.
#[derive(Debug, PartialEq)]
pub struct MapResults {
    pub name: String,
    pub values: Vec<Result<u32, String>>,
    pub marginals: Vec<Vec<u32>>,
    pub mpe: Vec<u16>,
    pub stream: Vec<(Result<u32, String>, Option<usize>)>,
    pub state_marginals: Vec<Vec<u32>>,
    pub fusion: Vec<Result<u32, String>>,
    pub fusion_state: Vec<Vec<u32>>,
}

pub fn results(r: &Report) -> Vec<MapResults> {
    r.maps
        .iter()
        .map(|m| MapResults {
            name: m.name.clone(),
            values: m.calls.iter().map(|c| c.value.clone()).collect(),
            marginals: m.marginals.clone(),
            mpe: m.mpe.clone(),
            stream: m
                .stream
                .iter()
                .map(|(c, p)| (c.value.clone(), *p))
                .collect(),
            state_marginals: m.state_marginals.clone(),
            fusion: m.fusion.iter().map(|c| c.value.clone()).collect(),
            fusion_state: m.fusion_state.clone(),
        })
        .collect()
}

/// The adversarial fusion sequence's exact outcome on module `M`, per phase: the
/// log-likelihood of the product of every observation (the stateless log-likelihood of
/// the `f64` log-domain reference rows, largest entry 1, plus `γ · max_c ln Π α`) and
/// the place's marginal (stateless `marginals` of the reference rows).
pub fn fusion_reference<M: CompiledMap<Scalar = f32>>() -> Vec<(f64, Vec<f64>)> {
    let (n, c, p) = (M::NUM_PLACES, M::NUM_CLASSES, evidence::FUSION_PLACE);
    let mut logs = vec![0.0f64; c];
    let mut row = vec![0.0f32; c];
    let mut out = vec![];
    for &(class, other, count) in &evidence::FUSION {
        evidence::favouring(class, other, &mut row);
        for (l, &a) in logs.iter_mut().zip(&row) {
            *l += f64::from(count) * f64::from(a).ln();
        }
        let best = logs.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let mut e = vec![M::ZERO_ROW; n];
        for (q, r) in e.iter_mut().enumerate() {
            for (k, x) in r.as_mut().iter_mut().enumerate() {
                *x = if q == p {
                    (logs[k] - best).exp() as f32
                } else {
                    1.0
                };
            }
        }
        let mut marg = vec![M::ZERO_ROW; n];
        let ll = f64::from(M::marginals(&e, &mut marg).unwrap());
        let ll = ll + f64::from(M::EVIDENCE_EXPONENT) * best;
        out.push((ll, marg[p].as_ref().iter().map(|&x| f64::from(x)).collect()));
    }
    out
}

/// Checks one map's adversarial fusion sequence (run on the target) against its exact
/// outcome: the log-likelihood of the product of the observations, and the place's
/// marginal on the class the net evidence favours.
pub fn check_fusion(target: &str, m: &MapReport, want: &[(f64, Vec<f64>)]) {
    let ctx = |phase: usize| format!("{target} {} fusion phase {phase}", m.name);
    assert_eq!(m.fusion.len(), evidence::FUSION.len(), "{}", ctx(0));
    assert_eq!(m.fusion_state.len(), want.len(), "{}", ctx(0));
    for (phase, (bits, (ll, row))) in m.fusion_state.iter().zip(want).enumerate() {
        let got: Vec<f64> = bits.iter().map(|&b| f64::from(f32::from_bits(b))).collect();
        assert!(
            (got[0] - ll).abs() <= 1e-5 * ll.abs().max(1.0),
            "{}: log-likelihood {} vs the product's {ll}",
            ctx(phase),
            got[0]
        );
        for (k, (g, w)) in got[1..].iter().zip(row).enumerate() {
            assert!(
                (g - w).abs() <= TOL,
                "{}: class {k}: {g} vs {w}",
                ctx(phase)
            );
        }
        let class = evidence::FUSION[phase].0;
        assert!(got[1 + class] > 0.999, "{}: {got:?}", ctx(phase));
    }
}

/// The firmware's streaming steps replayed on the in-process host build of a map:
/// the value of `set_all` + `log_likelihood` and of every step, the steps' places,
/// and the state's final marginals and evidence rows.
pub struct HostStream {
    pub values: Vec<f32>,
    pub places: Vec<usize>,
    pub marginals: Vec<Vec<f32>>,
    pub evidence: Vec<Vec<f32>>,
}

macro_rules! host_stream {
    ($m:ident, $index:expr) => {{
        let (rows, _) = inputs($index, $m::NUM_PLACES, $m::NUM_CLASSES, $m::UNKNOWN);
        let mut e: $m::Evidence = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        e.as_flattened_mut().copy_from_slice(&rows);
        let mut st = $m::State::new();
        st.set_all(&e).unwrap();
        let mut values = vec![st.log_likelihood().unwrap()];
        let mut places = vec![];
        let mut marg: $m::Marginals = [[0.0; $m::NUM_CLASSES]; $m::NUM_PLACES];
        let mut one = [0.0f32; $m::NUM_CLASSES];
        for i in 0..evidence::STEPS {
            let mut row = [0.0f32; $m::NUM_CLASSES];
            let p = evidence::step(evidence::SEED + $index, i, $m::NUM_PLACES, &mut row);
            places.push(p);
            st.observe(p, &row).unwrap();
            values.push(if i % 2 == 0 {
                st.marginals(&mut marg).unwrap()
            } else {
                st.marginal(p, &mut one).unwrap();
                one[0]
            });
        }
        st.marginals(&mut marg).unwrap();
        HostStream {
            values,
            places,
            marginals: marg.iter().map(|r| r.to_vec()).collect(),
            evidence: st.evidence().iter().map(|r| r.to_vec()).collect(),
        }
    }};
}

/// Checks one map's streaming steps against the host build's replay (values within
/// the tolerances, same places) and the state's final marginals against the
/// interpreter on the state's final evidence (`TreeInstance` for a tree mixture).
pub fn check_stream(target: &str, m: &MapReport, host: &HostStream) {
    let ctx = |what: &str| format!("{target} {} stream {what}", m.name);
    assert_eq!(m.stream.len(), host.values.len(), "{}", ctx("steps"));
    for (i, ((call, place), &want)) in m.stream.iter().zip(&host.values).enumerate() {
        let expected = match i {
            0 => "set_all",
            i if i % 2 == 1 => "observe_marginals",
            _ => "observe_marginal",
        };
        assert_eq!(call.name, expected, "{}", ctx("call order"));
        assert_eq!(
            *place,
            i.checked_sub(1).map(|s| host.places[s]),
            "{}",
            ctx("places")
        );
        let bits = call
            .value
            .as_ref()
            .unwrap_or_else(|e| panic!("{}: error {e}", ctx(&call.name)));
        let got = f64::from(f32::from_bits(*bits));
        let ok = if expected == "observe_marginal" {
            (got - f64::from(want)).abs() <= TOL
        } else {
            close(got, f64::from(want))
        };
        assert!(ok, "{}: step {i}: {got} vs host {want}", ctx(&call.name));
    }
    if m.name.ends_with("_trees") {
        let want = tree_reference(&m.name, &host.evidence).marginals().unwrap();
        for (p, row) in m.state_marginals.iter().enumerate() {
            for (k, &bits) in row.iter().enumerate() {
                let got = f64::from(f32::from_bits(bits));
                let (w, h) = (want.mixed.probs[p][k], f64::from(host.marginals[p][k]));
                assert!(
                    (got - w).abs() <= TOL && (got - h).abs() <= TOL,
                    "{}: place {p} class {k}: {got} vs TreeInstance {w} and host {h}",
                    ctx("final marginals")
                );
            }
        }
        return;
    }
    let demo = root().join("generated/demo");
    let inputs_ = Builder::new(demo.join("model.json"), demo.join(map_file(&m.name)))
        .seed(0)
        .count(5)
        .load()
        .unwrap();
    let inst = Instance::build(&inputs_.model, &inputs_.map, inputs_.decompositions).unwrap();
    let mut ev = Evaluator::new(&inst.spn).unwrap();
    let evidence = Evidence::from_rows(
        host.evidence
            .iter()
            .map(|r| r.iter().map(|&x| f64::from(x)).collect())
            .collect(),
    );
    let want = ev.marginals(&vec![None; m.places], &evidence).unwrap();
    for (p, row) in m.state_marginals.iter().enumerate() {
        for (k, &bits) in row.iter().enumerate() {
            let got = f64::from(f32::from_bits(bits));
            assert!(
                (got - want.probs[p][k]).abs() <= TOL
                    && (got - f64::from(host.marginals[p][k])).abs() <= TOL,
                "{}: place {p} class {k}: {got} vs interpreter {} and host {}",
                ctx("final marginals"),
                want.probs[p][k],
                host.marginals[p][k]
            );
        }
    }
}

/// The generator's state bytes (what `graphspn compile` prints) are every firmware
/// module's `STATE_BYTES`, for both families.
pub fn check_state_bytes(target: &str, r: &Report) {
    for m in &r.maps {
        let state = m.state_bytes.expect("state= in the map line");
        let b = firmware_builder(&m.name);
        let (_, report) = b.report_from_any(&b.load_any().unwrap()).unwrap();
        assert_eq!(
            report.state_bytes, state,
            "{target}: {}: the report's state bytes",
            m.name
        );
    }
}

/// The tree mixture of the 230-place map fits a small microcontroller: every call
/// takes at most 16 KiB of stack and the streaming state at most 64 KiB; on Cortex-M4F `log_likelihood` takes at most
/// 0.4 M instructions, `marginals` and `mpe` at most 1 M each; on the targets without
/// an FPU (Cortex-M3, RV32IMAC) `log_likelihood` at most 3 M and `marginals` 10 M.
pub fn check_tree_acceptance(target: &str, r: &Report) {
    let m = r
        .maps
        .iter()
        .find(|m| m.name == "saarbrucken_seq2_night1_trees")
        .expect("the 230-place tree mixture");
    let state = m.state_bytes.expect("state= in the map line");
    assert!(state <= 64 * 1024, "{target}: STATE_BYTES {state} > 64 KiB");
    let calls = m.calls.iter().chain(m.stream.iter().map(|(c, _)| c));
    let calls = calls.chain(&m.state_calls);
    for c in calls {
        assert!(
            c.stack <= 16 * 1024,
            "{target} {}: {} bytes of stack",
            c.name,
            c.stack
        );
    }
    // log_likelihood, marginals, mpe: the kernels' goals on a Cortex-M4F, and
    // log_likelihood and marginals on the targets without an FPU, whose mpe has
    // fixed-point max-product messages (2.81 M / 3.35 M; 7.41 M / 7.25 M with f32 ones).
    let limits: &[u64] = if target == M4F.target {
        &[400_000, 1_000_000, 1_000_000]
    } else {
        &[3_000_000, 10_000_000, 4_000_000]
    };
    for (c, &limit) in m.calls.iter().zip(limits) {
        assert!(
            c.instructions <= limit,
            "{target}: {} of the 230-place tree mixture takes {} instructions (at most {limit})",
            c.name,
            c.instructions
        );
    }
}

/// The fixed-point kernel's goals on the targets without an FPU: the 230-place
/// GraphSPN's `log_likelihood` in at most 3 M instructions and `marginals` in at most
/// 10 M (2.13 M / 9.90 M on RV32IMAC before the posterior pass summed in Q1.31).
pub fn check_fixed_point_goals(target: &str, r: &Report) {
    if !is_fixed(target) {
        return;
    }
    let m = r
        .maps
        .iter()
        .find(|m| m.name == "saarbrucken_seq2_night1")
        .expect("the 230-place GraphSPN");
    for (name, limit) in [("log_likelihood", 3_000_000), ("marginals", 10_000_000)] {
        let c = m.calls.iter().find(|c| c.name == name).expect("the call");
        assert!(
            c.instructions <= limit,
            "{target}: {name} of the 230-place GraphSPN takes {} instructions (at most {limit})",
            c.instructions
        );
    }
}

/// Median instructions of the steps of kind `name`.
pub fn median_instructions(m: &MapReport, name: &str) -> u64 {
    let mut n: Vec<u64> = m
        .stream
        .iter()
        .filter(|(c, _)| c.name == name)
        .map(|(c, _)| c.instructions)
        .collect();
    n.sort_unstable();
    n[n.len() / 2]
}
