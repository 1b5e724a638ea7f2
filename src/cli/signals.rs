//! SIGINT, SIGTERM and SIGHUP: the first asks the run to stop between levels or batches and
//! keep what it has; a second aborts at once, removing the temporary files being written.

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, OnceLock};

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

/// Records `sig`; the first sets `flag`, a second aborts.
fn on_signal(sig: i32, flag: &AtomicBool) {
    if RECEIVED
        .compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst)
        .is_ok()
    {
        flag.store(true, Ordering::SeqCst);
        eprintln!(
            "\n{}: stopping after the current step and writing what was found (send it again \
             to abort at once)",
            name(sig)
        );
    } else {
        isomesh::export::safe::remove_partials();
        eprintln!("\n{}: aborted; no further output written", name(sig));
        std::process::exit(i32::from(exit_status(sig)));
    }
}

#[cfg(unix)]
fn install(flag: Arc<AtomicBool>) -> std::io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            for sig in signals.forever() {
                on_signal(sig, &flag);
            }
        })?;
    Ok(())
}

#[cfg(not(unix))]
fn install(flag: Arc<AtomicBool>) -> std::io::Result<()> {
    // Ctrl-C is SIGINT's number, 2.
    ctrlc::set_handler(move || on_signal(2, &flag)).map_err(std::io::Error::other)
}
