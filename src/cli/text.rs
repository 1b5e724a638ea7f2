//! Text the command line echoes: numbers in a short form, user text cut and escaped,
//! standard output that tolerates a closed pipe, the topology summary and picture captions.

use isomesh::complex::Topology;

/// `x` as the shortest text that reads back to it, with an exponent when it is very large or
/// very small (`1e300`, not 301 digits).
pub fn num(x: f64) -> String {
    let a = x.abs();
    if x != 0.0 && a.is_finite() && !(1e-4..1e7).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

pub use isomesh::error::shown;

/// `println!` that goes quiet once standard output is closed (`isomesh check | head`).
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::cli::text::say_line(format_args!($($arg)*))
    };
}
pub(crate) use say;

/// Set once standard output is found closed.
static CLOSED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Writes one line to standard output; once the reader is gone (a closed pipe), the rest is
/// dropped quietly and the run goes on to its own exit status.
pub fn say_line(args: std::fmt::Arguments) {
    use std::io::Write;
    use std::sync::atomic::Ordering;
    if CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if out
        .write_fmt(args)
        .and_then(|()| out.write_all(b"\n"))
        .is_err()
    {
        CLOSED.store(true, Ordering::Relaxed);
    }
}

/// The readable topology summary.
pub(super) fn summary(t: &Topology, seconds: f64) -> String {
    let names = ["vertices", "edges", "faces", "3-cells"];
    let counts = |c: &[usize]| {
        c.iter()
            .enumerate()
            .map(|(j, n)| match names.get(j) {
                Some(name) => format!("{n} {name}"),
                None => format!("{n} {j}-cells"),
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut s = format!(
        "  complex: {}; Euler characteristic {} (built in {seconds:.3} s)",
        counts(&t.cells),
        t.euler_characteristic
    );
    let kind = match (t.manifold, t.closed) {
        (true, true) => "closed manifold",
        (true, false) => "manifold with boundary",
        (false, true) => "NOT a manifold (no boundary)",
        (false, false) => "NOT a manifold (with boundary)",
    };
    s += &format!(
        "\n  topology: {kind}, {} component{}",
        t.components,
        if t.components == 1 { "" } else { "s" }
    );
    if let Some(o) = t.orientable {
        s += if o {
            ", orientable"
        } else {
            ", non-orientable"
        };
    }
    if let Some(b) = &t.betti_mod2 {
        let b: Vec<String> = b.iter().map(usize::to_string).collect();
        s += &format!(", Betti numbers mod 2: {}", b.join(" "));
    }
    if !t.closed {
        s += &format!(
            "\n  boundary: {}; Euler characteristic {}",
            counts(&t.boundary_cells),
            t.boundary_euler_characteristic
        );
    }
    if !t.manifold {
        s += &format!(
            "\n  offenders: {} ridge{} without the right number of cofaces, {} edge{} left out",
            t.offender_count,
            if t.offender_count == 1 { "" } else { "s" },
            t.defects,
            if t.defects == 1 { "" } else { "s" }
        );
        for o in t.offenders.iter().take(5) {
            s += &format!(
                "\n    cell {} ({}): {} cofaces",
                o.cell,
                if o.on_boundary {
                    "boundary"
                } else {
                    "interior"
                },
                o.cofaces
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_stay_short() {
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(0.25), "0.25");
        assert_eq!(num(-2.5e-9), "-2.5e-9");
        assert_eq!(num(123456789.0), "1.23456789e8");
        assert_eq!(num(0.0), "0");
    }

    #[test]
    fn user_text_is_cut_and_escaped() {
        let long = "a".repeat(200_000);
        let s = shown(&format!("unknown name '{long}'"));
        assert!(s.len() < 200, "{s}");
        assert!(s.contains("200002 characters"), "{s}");
        let s = shown("bad\0byte\x07 here\nline two");
        assert!(!s.contains('\0') && !s.contains('\x07'), "{s:?}");
        assert!(s.contains("\\0") && s.contains("line two"), "{s}");
        let huge = "a b ".repeat(5000);
        assert!(shown(&huge).contains("more characters"));
    }
}
