//! Whether each step of a trace level runs on all the pool's threads or on the calling one
//! alone ([`crate::threads`]).
//!
//! A level's steps handle a few thousand items each. Some gain nearly a core per thread
//! (naming, deciding); others lose more to handing their data between cores than the
//! other cores give (ordering, a few merges of runs written on other cores), and how much
//! depends on the machine: where a cache line takes hundreds of nanoseconds to pass
//! between cores (cores on different dies, or a virtual machine's cores placed so, which
//! can change while a trace runs), more steps lose, and a trace on more threads could run
//! slower than on one.
//!
//! So each step runs one way, starting on all the threads, and now and then probes the
//! other way on one level. Adjacent levels are alike, so the probe's cost per frontier
//! simplex against the level before it says which way is cheaper: the step moves over
//! when two probes in a row find the other way cheaper by [`SWITCH`]. While they find it
//! dearer, it probes less often, and the less the dearer they find it ([`PROBE_COST`]),
//! down to one level in [`MAX_INTERVAL`]. The output does not depend on the way: a step's
//! result is the same on any number of threads.

use std::time::Duration;

/// The steps of a level that choose their threads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Step {
    /// Naming the exits whose new vertex is cached.
    Naming,
    /// Making the new vertices distinct, evaluating f there and caching them.
    Caching,
    /// Naming the exits of the cofacets whose new vertex was just cached.
    NamingDeferred,
    /// Sorting the named simplices and finding the distinct ones.
    Ordering,
    /// The oracle's decisions.
    Deciding,
    /// Gathering the crossed simplices, with their points where the domain needs them.
    Gathering,
    /// Taking the level into S and making it the next frontier.
    Accepting,
    /// A whole level: every step alone, or each step its own way.
    Level,
}

/// How many [`Step`]s there are.
const STEPS: usize = Step::Level as usize + 1;

/// Levels between probes at first, and after a move.
const MIN_INTERVAL: u32 = 8;
/// Most levels between probes.
const MAX_INTERVAL: u32 = 128;
/// What a probe may cost, as a share of its step's time: a probe that found the other way
/// dearer by a share r waits at least r / PROBE_COST levels for the next.
const PROBE_COST: f64 = 0.01;
/// A probe finds the other way cheaper when its cost per frontier simplex is below this
/// share of the level's before it.
const SWITCH: f64 = 0.85;
/// A level with fewer frontier simplices runs on one thread and is not counted: its
/// steps take microseconds, and the other threads would only wait on each other.
const FEWEST: usize = 64;

/// How the steps choose their threads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum Policy {
    /// As the probes find (the trace's way).
    #[default]
    Measured,
    /// The two ways in turn, level by level (to test that the way changes no output).
    #[cfg(test)]
    Alternate,
}

/// One step's way and what its probes found.
#[derive(Clone, Copy, Debug)]
struct Way {
    /// Whether it runs on all the threads.
    all: bool,
    /// The cost per frontier simplex, in seconds, of its last level run its way.
    last: Option<f64>,
    /// Levels between probes now, and levels left until the next.
    interval: u32,
    until: u32,
    /// Whether the last probe found the other way cheaper.
    doubt: bool,
    /// Levels counted (for [`Policy::Alternate`]).
    #[cfg(test)]
    runs: u32,
}

/// The ways the steps of a trace's levels run, and what their probes found.
pub(crate) struct StepThreads {
    policy: Policy,
    /// The pool's threads: with one, every step runs on it.
    threads: usize,
    ways: [Way; STEPS],
}

impl StepThreads {
    /// For a pool of `threads` threads.
    pub fn new(policy: Policy, threads: usize) -> Self {
        let way = Way {
            all: true,
            last: None,
            interval: MIN_INTERVAL,
            until: MIN_INTERVAL,
            doubt: false,
            #[cfg(test)]
            runs: 0,
        };
        StepThreads {
            policy,
            threads,
            ways: [way; STEPS],
        }
    }

    /// Whether `step`, on a level of `units` frontier simplices, runs on all the threads.
    pub fn all(&mut self, step: Step, units: usize) -> bool {
        if self.threads == 1 {
            return true;
        }
        let w = &mut self.ways[step as usize];
        match self.policy {
            #[cfg(test)]
            Policy::Alternate => {
                w.runs += 1;
                w.runs % 2 == 0
            }
            Policy::Measured => {
                if units < FEWEST {
                    return false;
                }
                // A probe once the step has a level to compare with.
                let probe = w.last.is_some() && w.until == 0;
                w.all != probe
            }
        }
    }

    /// Counts a level of `step` on `units` frontier simplices that took `took`, on all the
    /// threads or on one.
    pub fn record(&mut self, step: Step, all: bool, units: usize, took: Duration) {
        if self.threads == 1 || self.policy != Policy::Measured || units < FEWEST {
            return;
        }
        let cost = took.as_secs_f64() / units as f64;
        let w = &mut self.ways[step as usize];
        match w.last {
            Some(last) if all != w.all => {
                if cost < SWITCH * last {
                    if w.doubt {
                        // Two probes in a row: the step moves over.
                        w.all = all;
                        w.last = Some(cost);
                        w.interval = MIN_INTERVAL;
                        w.until = MIN_INTERVAL;
                        w.doubt = false;
                    } else {
                        // Probed again at the next level.
                        w.doubt = true;
                        w.until = 1;
                    }
                } else {
                    w.doubt = false;
                    let dearer = (cost / last - 1.0).max(0.0);
                    let wait = (dearer / PROBE_COST).min(f64::from(MAX_INTERVAL)) as u32;
                    w.interval = (2 * w.interval).max(wait).min(MAX_INTERVAL);
                    w.until = w.interval;
                }
            }
            _ => {
                w.last = Some(cost);
                w.until = w.until.saturating_sub(1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `levels` levels of `step` on 1,000 frontier simplices, each costing `one` or
    /// `all` microseconds the way it runs; returns how many ran on all the threads.
    fn run(t: &mut StepThreads, step: Step, levels: usize, one: u64, all: u64) -> usize {
        (0..levels)
            .filter(|_| {
                let on_all = t.all(step, 1000);
                let took = Duration::from_micros(if on_all { all } else { one });
                t.record(step, on_all, 1000, took);
                on_all
            })
            .count()
    }

    #[test]
    fn each_step_moves_to_the_way_its_probes_find_cheaper_and_probes_less_while_they_do_not() {
        let mut t = StepThreads::new(Policy::Measured, 2);
        // All threads cost a little less: a probe after 8 levels, then twice as many
        // levels between probes each time, up to 128.
        let levels = (8 + 1) + (16 + 1) + (32 + 1) + (64 + 1) + 2 * (128 + 1);
        let on_all = run(&mut t, Step::Naming, levels, 420, 400);
        assert_eq!(on_all, levels - 6);
        // Another step has its own way: one thread costs less there. Two probes in a row
        // (levels 9 and 11) find it; the step moves over and probes all the threads after
        // 8 levels, then (finding them dearer by half) 50, 100 and 128.
        let levels = 11 + (8 + 1) + (50 + 1) + (100 + 1) + (128 + 1);
        let on_all = run(&mut t, Step::Ordering, levels, 200, 300);
        assert_eq!(on_all, 8 + 1 + 4);
        assert!(!t.ways[Step::Ordering as usize].all);
        // The machine changes: all threads now cost more for naming. Its next probes of
        // one thread, 128 levels on, see it, and the step moves over.
        let on_all = run(&mut t, Step::Naming, 128 + 3 + 100, 600, 900);
        assert!(!t.ways[Step::Naming as usize].all);
        // 128 levels, the one between the two probes, and probes of all the threads after
        // 8 and 50 levels.
        assert_eq!(on_all, 128 + 1 + 2);
        // A way far dearer is probed after 128 levels from the first probe on.
        let mut t = StepThreads::new(Policy::Measured, 2);
        let levels = (8 + 1) + 2 * (128 + 1);
        assert_eq!(run(&mut t, Step::Deciding, levels, 1000, 400), levels - 3);
        // Noise: a probe that finds the other way cheaper once, not twice, moves nothing.
        let mut t = StepThreads::new(Policy::Measured, 2);
        let mut on_all = 0;
        for level in 0..200 {
            let all = t.all(Step::Deciding, 1000);
            on_all += usize::from(all);
            let micros = match (all, level) {
                (true, _) => 400,
                // The first probe.
                (false, 8) => 300,
                (false, _) => 600,
            };
            t.record(Step::Deciding, all, 1000, Duration::from_micros(micros));
        }
        assert!(t.ways[Step::Deciding as usize].all);
        // Probes at levels 8 and 10, then 50 and 100 levels apart.
        assert_eq!(on_all, 200 - 4);
    }

    #[test]
    fn small_levels_and_one_thread_pools_are_not_timed() {
        let mut t = StepThreads::new(Policy::Measured, 2);
        assert!(!t.all(Step::Deciding, FEWEST - 1));
        t.record(Step::Deciding, false, FEWEST - 1, Duration::from_secs(1));
        assert!(t.ways[Step::Deciding as usize].last.is_none());
        // A level to compare with comes first: no probe before it.
        assert!(t.all(Step::Deciding, 1000));
        let mut one = StepThreads::new(Policy::Measured, 1);
        assert!(one.all(Step::Deciding, 1000));
        one.record(Step::Deciding, true, 1000, Duration::from_secs(1));
        assert!(one.ways[Step::Deciding as usize].last.is_none());
        let mut turns = StepThreads::new(Policy::Alternate, 2);
        let ways: Vec<bool> = (0..4).map(|_| turns.all(Step::Accepting, 10)).collect();
        assert_eq!(ways, [false, true, false, true]);
    }
}
