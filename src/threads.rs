//! How many threads the crate's parallel steps split their work among: the rayon pool's,
//! or only the calling one while it holds an [`Alone`] guard ([`alone_if`]). A step of a
//! trace level that loses more to handing its data between cores than it gains from them
//! (as where a cache line takes hundreds of nanoseconds to pass between cores) runs this
//! way, with no task handed to another thread.
//!
//! Every parallel loop of a trace level asks [`threads`] (or [`min_len`]) before it splits.

use std::cell::Cell;

thread_local! {
    /// Whether this thread runs its parallel steps alone.
    static ALONE: Cell<bool> = const { Cell::new(false) };
}

/// While it lives, the thread that made it runs its parallel steps alone (see
/// [`alone_if`]); dropped, the flag is as it was, after a panic too.
#[must_use = "the flag is restored when this is dropped"]
pub(crate) struct Alone(bool);

impl Drop for Alone {
    fn drop(&mut self) {
        ALONE.set(self.0);
    }
}

/// The threads a parallel step may split its work among: 1 on a thread that runs its steps
/// alone, else the current pool's.
#[inline]
pub(crate) fn threads() -> usize {
    if ALONE.get() {
        1
    } else {
        rayon::current_num_threads()
    }
}

/// Makes the calling thread run its parallel steps alone, when `alone`, until the returned
/// guard is dropped.
pub(crate) fn alone_if(alone: bool) -> Alone {
    Alone(ALONE.replace(alone || ALONE.get()))
}

/// The fewest items per piece of a parallel iterator that wants `items`: all of them (one
/// piece, run by the calling thread) when the step runs alone.
#[inline]
pub(crate) fn min_len(items: usize) -> usize {
    if ALONE.get() {
        usize::MAX
    } else {
        items
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// Runs `f`, whose parallel steps then run on the calling thread only.
    fn on_one_thread<R>(f: impl FnOnce() -> R) -> R {
        let _alone = alone_if(true);
        f()
    }

    #[test]
    fn alone_a_parallel_loop_stays_on_the_calling_thread_and_the_flag_comes_back() {
        let p = crate::test_pool(2);
        p.install(|| {
            assert_eq!(threads(), 2);
            let me = rayon::current_thread_index();
            let seen: Vec<Option<usize>> = on_one_thread(|| {
                assert_eq!(threads(), 1);
                // Nested, and the flag is still set after it.
                on_one_thread(|| assert_eq!(threads(), 1));
                assert_eq!(threads(), 1);
                (0..100_000)
                    .into_par_iter()
                    .with_min_len(min_len(1))
                    .map(|_| rayon::current_thread_index())
                    .collect()
            });
            assert!(seen.iter().all(|&t| t == me));
            assert_eq!(threads(), 2);
            assert_eq!(min_len(5), 5);
            let out = std::panic::catch_unwind(|| on_one_thread(|| panic!("inside")));
            assert!(out.is_err());
            assert_eq!(threads(), 2, "the flag stayed set after a panic");
            {
                let _not = alone_if(false);
                assert_eq!(threads(), 2);
                let _alone = alone_if(true);
                assert_eq!(threads(), 1);
                // Within a thread that runs alone, `false` does not undo it.
                let _still = alone_if(false);
                assert_eq!(threads(), 1);
            }
            assert_eq!(threads(), 2);
        });
    }
}
