//! The memory limit holds while equations are parsed, differentiated and compiled: measured
//! in this process with the counting allocator, as the `isomesh` binary measures its heap.
//! One test only, so that no other test's allocations share the counters.

use isomesh::expr::{ErrorKind, Spec};
use isomesh::memory::{self, CountingAlloc};
use isomesh::Error;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

/// A sphere plus a long sum scaled to nothing much: every term has a derivative, so
/// differentiating and compiling need several times what the parsed tree does.
fn spec(terms: usize) -> String {
    let sum: Vec<String> = (0..terms)
        .map(|i| match i % 3 {
            0 => format!("{}*x*y", i % 7 + 1),
            1 => format!("sin({}*z)", i % 5 + 1),
            _ => format!("exp(-{}*x*z)", i % 4 + 1),
        })
        .collect();
    format!(
        "ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - 1 + 1e-12*({})\"]\nseeds = [[1, 0, 0]]\n",
        sum.join(" + ")
    )
}

/// Resolves `text` under `limit`: the result and the peak heap above what was live before.
fn resolve_within(text: &str, limit: u64) -> (isomesh::Result<()>, u64) {
    memory::reset_peak();
    let r = memory::within(limit, || Spec::from_toml(text)?.resolve("long").map(drop));
    (r, memory::peak_bytes() as u64)
}

#[test]
fn parsing_differentiating_and_compiling_stop_at_the_memory_limit() {
    let text = spec(200_000);
    let (r, need) = resolve_within(&text, u64::MAX);
    r.expect("resolves with no limit");
    let base = memory::live_bytes() as u64;
    assert!(
        need > base + (32 << 20),
        "the sum needs {need} bytes, too few to test"
    );

    // Limits from a tenth of what it needs to 99%: each stops, in the phase it had reached,
    // with its peak heap within 10% of the limit.
    let mut phases = Vec::new();
    for permille in [100, 300, 500, 700, 900, 950, 990] {
        let limit = base + (need - base) * permille / 1000;
        let (r, peak) = resolve_within(&text, limit);
        let phase = match r {
            Err(Error::Parse(e)) if e.kind == ErrorKind::TooLarge => {
                assert!(e.message.contains("memory limit"), "{e}");
                "parsing"
            }
            Err(e @ Error::MemoryLimit { .. }) => {
                assert!(e.to_string().contains("--max-memory"), "{e}");
                let e = e.to_string();
                ["reading", "differentiating", "compiling"]
                    .into_iter()
                    .find(|p| e.starts_with(p))
                    .unwrap_or_else(|| panic!("which phase: {e}"))
            }
            other => panic!("limit {limit} of {need}: {other:?}"),
        };
        assert!(
            peak as f64 <= 1.1 * limit as f64,
            "{phase}: peak {peak} over the limit {limit} (unlimited: {need})"
        );
        eprintln!("limit {limit} of {need}: stopped {phase}, peak {peak}");
        phases.push(phase);
    }
    // The limit is checked in more than one phase, not only at the end.
    assert!(phases.contains(&"parsing"), "{phases:?}");
    assert!(phases.contains(&"differentiating"), "{phases:?}");

    // Under a limit it fits, it resolves as before.
    let (r, _) = resolve_within(&text, need + (need >> 2));
    r.expect("resolves within a limit above its need");
}
