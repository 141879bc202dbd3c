//! Living and dying with a parent process. `holodeck run` starts its server,
//! samplers and display with `--exit-with-parent` and a pipe on their standard
//! input that it never writes to. When the parent ends, however it ends (a
//! SIGKILL included), the pipe reads end-of-file and the child stops as it
//! does on SIGTERM: a server flushes and closes its file first. On Linux the
//! kernel also sends SIGTERM when the parent dies (a parent-death signal), in
//! case the child is too busy to notice the pipe.

use std::io::Read;
use std::time::Duration;

/// How long a child that was told to stop may take before it exits anyway.
const GRACE: Duration = Duration::from_secs(60);

/// Makes this process stop when its parent does (see the module docs).
pub fn exit_with_parent() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: prctl with PR_SET_PDEATHSIG takes a signal number and has no memory effects.
        unsafe {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
        }
    }
    // SAFETY: getppid has no preconditions.
    if unsafe { libc::getppid() } == 1 {
        // The parent is already gone (adopted by init before the signal was set up).
        terminate();
    }
    std::thread::spawn(|| {
        let mut stdin = std::io::stdin();
        let mut buf = [0u8; 256];
        while matches!(stdin.read(&mut buf), Ok(n) if n > 0) {}
        tracing::warn!("the parent process is gone: stopping");
        terminate();
    });
}

/// Stops this process as SIGTERM does, and exits anyway after a grace period.
fn terminate() {
    // SAFETY: sending a signal to ourselves has no memory effects.
    unsafe {
        libc::kill(libc::getpid(), libc::SIGTERM);
    }
    std::thread::sleep(GRACE);
    std::process::exit(1);
}
