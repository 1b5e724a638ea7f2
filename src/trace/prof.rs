//! TEMP phase timers.
use std::sync::atomic::{AtomicU64, Ordering};
pub static T: [AtomicU64; 16] = [const { AtomicU64::new(0) }; 16];
pub fn add(i: usize, t: std::time::Instant) { T[i].fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed); }
pub fn dump() { if std::env::var("PROF").is_ok() { let names=["name","deferred","sortfirst","judge","takenorder","retry","found","accept","extent","step_total","other","av_sort","av_decode","av_eval","av_insert","acc_insert"]; for (i,n) in names.iter().enumerate(){ eprintln!("{n:12} {:.4}", T[i].load(Ordering::Relaxed) as f64*1e-9);} } }
