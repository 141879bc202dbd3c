//! Processes a command starts and watches (`holodeck run`'s server,
//! samplers and display): this program as a child that dies with its
//! parent, a child that is killed if dropped still running, how a process
//! ended in words, and SIGINT/SIGTERM noted for a clean stop.

use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

/// This program as a child command: it ends when this process ends, and
/// logs as this process does.
pub fn me() -> Result<Command> {
    let mut cmd = Command::new(std::env::current_exe().context("finding the holodeck executable")?);
    // The child watches its standard input: when this process ends, it stops
    // too; and it logs as this process does (-q, -v).
    cmd.arg("--exit-with-parent")
        .args(holodeck_cli::verbosity::child_args())
        .stdin(Stdio::piped());
    Ok(cmd)
}

/// A process `run` started, named for messages. Dropping it kills the
/// process if it still runs, so an error in `run` leaves nothing behind.
pub struct Child {
    /// Its name in messages ("server", "sampler 2").
    pub name: String,
    /// The process.
    pub process: std::process::Child,
    /// Set once its exit has been reported (or was expected).
    pub done: bool,
}

impl Child {
    /// Starts `cmd`, named `name` for messages.
    pub fn spawn(name: impl Into<String>, mut cmd: Command) -> Result<Child> {
        let name = name.into();
        let process = cmd.spawn().with_context(|| format!("starting the {name}"))?;
        Ok(Child {
            name,
            process,
            done: false,
        })
    }

    /// The exit status, if it has exited.
    pub fn exited(&mut self) -> Result<Option<ExitStatus>> {
        self.process
            .try_wait()
            .with_context(|| format!("waiting for the {}", self.name))
    }

    /// Waits up to `limit` for it to exit; kills it after that. Returns what
    /// went wrong, if anything: a failure or signal, or having to be killed.
    pub fn finish(&mut self, limit: Duration) -> Option<String> {
        let start = Instant::now();
        loop {
            match self.process.try_wait() {
                Ok(Some(status)) => {
                    self.done = true;
                    return (!status.success()).then(|| format!("the {} {}", self.name, how(status)));
                }
                Ok(None) if start.elapsed() < limit => std::thread::sleep(Duration::from_millis(50)),
                _ => {
                    let _ = self.process.kill();
                    let _ = self.process.wait();
                    self.done = true;
                    return Some(format!(
                        "the {} did not stop within {limit:?} and was killed",
                        self.name
                    ));
                }
            }
        }
    }
}

impl Drop for Child {
    fn drop(&mut self) {
        if !self.done && matches!(self.process.try_wait(), Ok(None)) {
            let _ = self.process.kill();
            let _ = self.process.wait();
        }
    }
}

/// How a process ended, in words.
pub fn how(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (_, Some(sig)) => {
            let name = match sig {
                libc::SIGKILL => " (SIGKILL)",
                libc::SIGTERM => " (SIGTERM)",
                libc::SIGINT => " (SIGINT)",
                libc::SIGSEGV => " (SIGSEGV)",
                libc::SIGABRT => " (SIGABRT)",
                _ => "",
            };
            format!("was killed by signal {sig}{name}")
        }
        (Some(code), None) => format!("failed with exit status {code}"),
        (None, None) => "ended for an unknown reason".into(),
    }
}

/// The signal (SIGINT or SIGTERM) that asked the command to stop, 0 for none.
static STOP_SIGNAL: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);

extern "C" fn note_stop(signal: libc::c_int) {
    STOP_SIGNAL.store(signal, std::sync::atomic::Ordering::Relaxed);
}

/// Makes SIGINT and SIGTERM (Ctrl-C, `kill PID`) only noted, for the
/// command to stop as it should ([`stop_signal`]): `run` as its TIME would
/// (the server flushes and quits, the samplers and display stop, the
/// summary is printed), `sample` saying what it traced; both exit 128 + the
/// signal.
pub fn stop_on_signals() {
    for signal in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: the handler only stores to an atomic, which is
        // async-signal-safe; the action struct is fully initialised.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = note_stop as extern "C" fn(libc::c_int) as usize;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

/// The signal that asked the command to stop, if one did.
pub fn stop_signal() -> Option<libc::c_int> {
    match STOP_SIGNAL.load(std::sync::atomic::Ordering::Relaxed) {
        0 => None,
        s => Some(s),
    }
}
