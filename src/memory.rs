//! Memory accounting: a counting global allocator (for peak heap figures) and the default
//! memory limit.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The system allocator, counting live and peak heap bytes. Binaries opt in with
/// `#[global_allocator] static A: isomesh::memory::CountingAlloc = CountingAlloc;`;
/// without it [`peak_bytes`] reports 0.
pub struct CountingAlloc;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

#[inline]
fn grow(n: usize) {
    let live = LIVE.fetch_add(n, Ordering::Relaxed) + n;
    PEAK.fetch_max(live, Ordering::Relaxed);
}

// SAFETY: every call forwards to `System` with the caller's layout; the counters are atomics.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc_zeroed(layout);
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout);
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = System.realloc(ptr, layout, new_size);
        if !p.is_null() {
            if new_size >= layout.size() {
                grow(new_size - layout.size());
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

/// Heap bytes live now (0 unless [`CountingAlloc`] is the global allocator).
pub fn live_bytes() -> usize {
    LIVE.load(Ordering::Relaxed)
}

/// Highest live heap since the start or the last [`reset_peak`].
pub fn peak_bytes() -> usize {
    PEAK.load(Ordering::Relaxed)
}

/// Heap bytes in use: the counted live heap where [`CountingAlloc`] is the global allocator,
/// else `estimate` (what the caller knows it holds).
pub fn in_use(estimate: usize) -> u64 {
    match live_bytes() {
        0 => estimate as u64,
        live => live as u64,
    }
}

/// Fails when `extra` more heap bytes, for `what`, would pass `limit`.
pub fn check_headroom(what: &str, extra: usize, limit: u64) -> crate::Result<()> {
    let live = in_use(0);
    let need = live.saturating_add(extra as u64);
    if need > limit {
        let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
        return Err(crate::Error::Trace(format!(
            "{what} needs about {:.1} MiB on top of {:.1} MiB in use, over the memory limit of \
             {:.1} MiB (raise --max-memory, or use a larger edge)",
            mib(extra as u64),
            mib(live),
            mib(limit)
        )));
    }
    Ok(())
}

thread_local! {
    /// The heap limit that parsing and compiling on this thread check (see [`within`]).
    static LIMIT: Cell<u64> = const { Cell::new(u64::MAX) };
}

/// Runs `f` with a heap limit of `limit` bytes for the work on this thread that checks
/// [`over_limit`]: parsing equations, differentiating and compiling them. Such work stops
/// with an error once the counted heap passes the limit, instead of growing without one.
///
/// ```
/// use isomesh::expr::Spec;
/// use isomesh::memory::{within, CountingAlloc};
///
/// #[global_allocator]
/// static ALLOC: CountingAlloc = CountingAlloc;
///
/// fn main() {
///     // A 20,000-term equation under a 1 MiB limit is refused, not parsed; under 1 GiB it
///     // resolves.
///     let long = vec!["x*y"; 20_000].join(" + ");
///     let text = format!("ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - 1 + ({long})\"]\n");
///     let resolve = || Spec::from_toml(&text)?.resolve("long");
///     let err = within(1 << 20, resolve).unwrap_err();
///     assert!(err.to_string().contains("memory limit"), "{err}");
///     assert!(within(1 << 30, resolve).is_ok());
/// }
/// ```
pub fn within<T>(limit: u64, f: impl FnOnce() -> T) -> T {
    struct Restore(u64);
    impl Drop for Restore {
        fn drop(&mut self) {
            LIMIT.set(self.0);
        }
    }
    let _restore = Restore(LIMIT.replace(limit));
    f()
}

/// The limit set by [`within`] when the counted heap is over it (never without
/// [`CountingAlloc`], whose count is then 0).
pub fn over_limit() -> Option<u64> {
    let limit = LIMIT.get();
    (live_bytes() as u64 > limit).then_some(limit)
}

/// An error when `bytes` more would take the counted heap past this thread's limit (set by
/// [`within`]): for work that needs a known amount at once, checked before it starts.
pub(crate) fn ensure_room(what: &str, bytes: u64, advice: &str) -> crate::Result<()> {
    let limit = LIMIT.get();
    if live_bytes() > 0 && (live_bytes() as u64).saturating_add(bytes) > limit {
        return Err(crate::Error::MemoryLimit {
            what: format!("{what} (about {})", human_bytes(bytes)),
            limit,
            advice: advice.into(),
        });
    }
    Ok(())
}

/// Counts the steps of a long computation (parsing, differentiating, compiling) and checks
/// [`over_limit`] once every 1024 of them; unchecked ones never fail.
pub(crate) struct Ticks {
    n: u32,
    checked: bool,
}

impl Ticks {
    /// Steps that check this thread's limit.
    pub(crate) fn checked() -> Self {
        Ticks {
            n: 0,
            checked: true,
        }
    }

    /// Steps that never fail.
    pub(crate) fn unchecked() -> Self {
        Ticks {
            n: 0,
            checked: false,
        }
    }

    /// One step: `Err(limit)` when the heap has passed this thread's limit.
    #[inline]
    pub(crate) fn tick(&mut self) -> Result<(), u64> {
        self.n = self.n.wrapping_add(1);
        if self.checked && self.n % 1024 == 0 {
            if let Some(limit) = over_limit() {
                return Err(limit);
            }
        }
        Ok(())
    }
}

/// Restarts peak tracking from the current live size.
pub fn reset_peak() {
    PEAK.store(LIVE.load(Ordering::Relaxed), Ordering::Relaxed);
}

/// Total physical memory in bytes, from /proc/meminfo where there is one.
pub fn total_ram() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The default memory limit: 3/4 of physical memory, or 8 GiB when that is unknown.
pub fn default_limit() -> u64 {
    total_ram().map_or(8 << 30, |r| r / 4 * 3)
}

/// A byte count with a unit that shows it (B, KiB, MiB, GiB, TiB), three significant digits.
pub fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} B")
    } else if v < 10.0 {
        format!("{v:.2} {}", UNITS[u])
    } else if v < 100.0 {
        format!("{v:.1} {}", UNITS[u])
    } else {
        format!("{v:.0} {}", UNITS[u])
    }
}
