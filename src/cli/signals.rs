//! SIGINT, SIGTERM and SIGHUP: the first asks the run to stop between levels or batches and
//! keep what it has; a second aborts at once, removing the temporary files being written.
//!
//! A supervisor that signals the process and then its process group (GNU `timeout`, shells,
//! job runners) delivers one request twice: the same signal from the same process within a
//! moment of the first counts once. A second Ctrl-C (sent by the kernel) or a second `kill`
//! (another process) still aborts.

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// How soon after the first a signal from the same sender counts as the same request.
const REPEAT_WINDOW: Duration = Duration::from_secs(2);

/// The first signal received (0: none).
static RECEIVED: AtomicI32 = AtomicI32::new(0);

/// The stop flag the trace polls, set by the first signal; handlers are installed once.
pub fn stop_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        // If the handlers cannot be installed, the signals keep their default meaning.
        let _ = install(flag.clone());
        flag
    })
    .clone()
}

/// The signal that stopped the run, if one did.
pub fn received() -> Option<i32> {
    match RECEIVED.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// The conventional exit status after signal `sig`: 128 + its number.
pub fn exit_status(sig: i32) -> u8 {
    u8::try_from(128 + sig).unwrap_or(255)
}

/// The name of signal `sig` (SIGINT, SIGTERM, SIGHUP).
pub fn name(sig: i32) -> String {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        match sig {
            SIGINT => return "SIGINT".into(),
            SIGTERM => return "SIGTERM".into(),
            SIGHUP => return "SIGHUP".into(),
            _ => {}
        }
    }
    format!("signal {sig}")
}

/// Who sent the first signal (`None`: the kernel, as for Ctrl-C), and when.
static FIRST: Mutex<Option<(Option<i32>, Instant)>> = Mutex::new(None);

/// Whether `sig` from `sender` repeats the first signal: the same signal from the same
/// process, within [`REPEAT_WINDOW`] of it.
fn repeats_first(sig: i32, sender: Option<i32>) -> bool {
    let first = FIRST.lock().unwrap_or_else(|e| e.into_inner());
    match (*first, sender) {
        (Some((Some(pid), at)), Some(now)) => {
            RECEIVED.load(Ordering::SeqCst) == sig && pid == now && at.elapsed() < REPEAT_WINDOW
        }
        _ => false,
    }
}

/// Records `sig` sent by process `sender`; the first sets `flag`, a second aborts unless it
/// only repeats the first.
fn on_signal(sig: i32, sender: Option<i32>, flag: &AtomicBool) {
    if RECEIVED
        .compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst)
        .is_ok()
    {
        *FIRST.lock().unwrap_or_else(|e| e.into_inner()) = Some((sender, Instant::now()));
        flag.store(true, Ordering::SeqCst);
        eprintln!(
            "\n{}: stopping after the current step and writing what was found (send it again \
             to abort at once)",
            name(sig)
        );
    } else if !repeats_first(sig, sender) {
        isomesh::export::safe::remove_partials();
        eprintln!("\n{}: aborted; no further output written", name(sig));
        std::process::exit(i32::from(exit_status(sig)));
    }
}

#[cfg(unix)]
fn install(flag: Arc<AtomicBool>) -> std::io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    use signal_hook::iterator::exfiltrator::WithOrigin;
    let mut signals =
        signal_hook::iterator::SignalsInfo::<WithOrigin>::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            for origin in signals.forever() {
                on_signal(origin.signal, origin.process.map(|p| p.pid), &flag);
            }
        })?;
    Ok(())
}

#[cfg(not(unix))]
fn install(flag: Arc<AtomicBool>) -> std::io::Result<()> {
    // Ctrl-C is SIGINT's number, 2.
    ctrlc::set_handler(move || on_signal(2, None, &flag)).map_err(std::io::Error::other)
}
