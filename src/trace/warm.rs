//! Keeps the pool's threads awake while a trace runs. A level holds a few parallel steps
//! of tens to hundreds of microseconds, separated by short sequential ones; an idle rayon
//! thread goes to sleep after a few dozen microseconds, and waking it costs about as much
//! again (measured near 90 µs on a 2-core virtual machine), so small levels would run on
//! one thread. While [`warm`] runs its closure, the other threads of the pool poll for work
//! instead of sleeping, yielding the core to the system scheduler when there is none.

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};

thread_local! {
    /// Whether this thread is polling already (a poller may pick up another one).
    static POLLING: Cell<bool> = const { Cell::new(false) };
}

/// Sets the flag when dropped, so that pollers stop on an early return or a panic too.
struct Release<'a>(&'a AtomicBool);

impl Drop for Release<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// Runs `f` on a thread of the current pool while the pool's other threads poll for its
/// parallel work. With one thread this is `f()` in `rayon::scope`.
pub(crate) fn warm<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    let done = AtomicBool::new(false);
    rayon::scope(|s| {
        let owner = rayon::current_thread_index();
        let release = Release(&done);
        for _ in 1..rayon::current_num_threads() {
            let done = &done;
            s.spawn(move |_| poll(done, owner));
        }
        let out = f();
        drop(release);
        out
    })
}

/// [`warm`] when `on`, else `f()` as it is.
pub(crate) fn maybe<R: Send>(on: bool, f: impl FnOnce() -> R + Send) -> R {
    if on {
        warm(f)
    } else {
        f()
    }
}

/// Runs the pool's pending jobs until `done`. Returns at once on the thread running the
/// trace (which would otherwise wait on itself) and on a thread polling already.
fn poll(done: &AtomicBool, owner: Option<usize>) {
    if rayon::current_thread_index() == owner || POLLING.get() {
        return;
    }
    POLLING.set(true);
    while !done.load(Ordering::Acquire) {
        if rayon::yield_now() != Some(rayon::Yield::Executed) {
            std::thread::yield_now();
        }
    }
    POLLING.set(false);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    #[test]
    fn parallel_work_inside_gives_the_same_results_and_the_pollers_stop() {
        let want: u64 = (0..100_000u64).map(|i| i * i % 7).sum();
        for threads in [1, 2, 4] {
            let p = crate::test_pool(threads);
            let got = p.install(|| {
                warm(|| {
                    (0..50)
                        .map(|_| (0..100_000u64).into_par_iter().map(|i| i * i % 7).sum())
                        .collect::<Vec<u64>>()
                })
            });
            assert!(got.iter().all(|&g| g == want), "{threads} threads");
            // Nested, and on a thread outside any pool.
            let nested: u64 = p.install(|| warm(|| warm(|| (0..1000u64).into_par_iter().sum())));
            assert_eq!(nested, 499_500);
            assert_eq!(warm(|| 7), 7);
        }
    }

    #[test]
    fn a_panic_inside_reaches_the_caller_and_leaves_the_pool_usable() {
        let p = crate::test_pool(2);
        let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            p.install(|| warm(|| -> u64 { panic!("inside") }))
        }));
        assert!(out.is_err());
        let sum: u64 = p.install(|| (0..1000u64).into_par_iter().sum());
        assert_eq!(sum, 499_500);
    }
}
