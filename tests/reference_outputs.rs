//! The outputs of the benchmarks' reference cases (`benches/reference.toml`), recorded as
//! hashes: the keys of S in their order, and for the complexes the benchmarks time, every
//! cell's facet list and every polygon. Work on speed must leave them exactly as they are;
//! a change of output is a decision to make on purpose, with new hashes.

use isomesh::bench::{trace_case, ReferenceCase};
use isomesh::complex::{Complex, Surface};
use isomesh::trace::{CpuOracle, Sample};

/// FNV-1a over 64-bit words: stable across platforms and Rust releases.
#[derive(Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn word(&mut self, w: u64) {
        for b in w.to_le_bytes() {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

/// The keys of S in sample order.
fn keys_hash(s: &Sample) -> u64 {
    let mut h = Fnv::new();
    for i in 0..s.len() {
        s.key(i).iter().for_each(|&w| h.word(w));
    }
    h.0
}

/// Every level's facet lists in order, then the polygons (m >= 2) in order.
fn complex_hash(c: &Complex, surface: Option<&Surface>) -> u64 {
    let mut h = Fnv::new();
    for j in 1..=c.dim() {
        let level = c.level(j);
        h.word(level.len() as u64);
        for i in 0..level.len() {
            let facets = level.facets(i);
            h.word(facets.len() as u64);
            facets.iter().for_each(|&f| h.word(u64::from(f)));
        }
    }
    if let Some(s) = surface {
        for i in 0..s.len() {
            let poly = s.polygon(i);
            h.word(poly.len() as u64);
            poly.iter().for_each(|&v| h.word(u64::from(v)));
        }
    }
    h.0
}

/// (short name, |S|, keys hash, complex hash for the cases whose complex is benchmarked),
/// on isomesh's own triangulation of each case (the C++ counts in `benches/reference.toml`
/// are on the reference's matrix and offset).
const RECORDED: &[(&str, usize, u64, Option<u64>)] = &[
    ("S2/R3", 16264, 0xa70687c9bb83cba9, Some(0xc7981033fc4e7927)),
    ("chair", 11734, 0xf89aee967fd1ebdd, Some(0x1cd3b5dec72e50c9)),
    (
        "T2/R4",
        123720,
        0x915c43bcbbbadd95,
        Some(0xf8c0d2284cb5c58e),
    ),
    ("S2/R8", 20370, 0x375439b0dcdd4331, None),
    ("T2/R10", 499790, 0xb58bb988ce6158a7, None),
    ("T3/R6", 465284, 0x4d38b2a474525645, None),
];

#[test]
fn reference_cases_trace_and_mesh_exactly_as_recorded() {
    let cases = ReferenceCase::parse_all(include_str!("../benches/reference.toml")).unwrap();
    assert_eq!(cases.len(), RECORDED.len(), "a case without a record");
    let mut seen = Vec::new();
    for case in &cases {
        let p = case.problem().unwrap();
        let s = trace_case(&p, &CpuOracle::new(&p.system)).unwrap();
        let complex = RECORDED
            .iter()
            .find(|r| r.0 == case.short)
            .and_then(|r| r.3)
            .map(|_| {
                let c = Complex::build(&s, &p.system, None).unwrap();
                let surface = (c.dim() >= 2).then(|| Surface::new(&c, Some(&p.system)));
                complex_hash(&c, surface.as_ref())
            });
        seen.push((case.short.clone(), s.len(), keys_hash(&s), complex));
    }
    let shown: Vec<String> = seen
        .iter()
        .map(|(n, len, k, c)| {
            let c = c.map_or("None".into(), |c| format!("Some({c:#018x})"));
            format!("(\"{n}\", {len}, {k:#018x}, {c}),")
        })
        .collect();
    for (got, want) in seen.iter().zip(RECORDED) {
        assert_eq!(
            (got.0.as_str(), got.1, got.2, got.3),
            *want,
            "outputs changed; now:\n{}",
            shown.join("\n")
        );
    }
}
