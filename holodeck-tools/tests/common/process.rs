//! Child processes of the tests, never left behind, never waited on forever.
//!
//! A [`Proc`] starts its child in a process group of its own and ends that
//! group by the child's PID when the guard drops, whether the test passed or
//! panicked; should the test process itself die, the kernel kills the child
//! (`PR_SET_PDEATHSIG`) and the child's standard input reaches end of file.
//! Everything a child prints is captured line by line, so a test waits for
//! what the child says (a log line, a report) under one generous [`DEADLINE`]
//! instead of sleeping and hoping. Nothing here may sleep to let something
//! happen, or compare a duration with a bound to decide a test.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::CommandExt;
use std::process::{Child, ChildStdin, Command, ExitStatus, Output, Stdio};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// How long a test waits for anything at all. Generous: a loaded machine
/// makes a test slow, never wrong; a hang fails with what was awaited.
pub const DEADLINE: Duration = Duration::from_secs(120);

/// Polls `probe` until it gives an answer; fails after `deadline`, naming
/// `what` was awaited.
pub fn wait_for<T>(what: &str, deadline: Duration, mut probe: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(answer) = probe() {
            return answer;
        }
        assert!(start.elapsed() < deadline, "waited {deadline:?} for {what}, in vain");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Lines a child printed, on either stream, in the order they were read.
#[derive(Default)]
struct Captured {
    lines: Vec<(Source, String)>,
    /// Streams not yet at end of file.
    open: usize,
}

/// Which stream a line came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    Stdout,
    Stderr,
}

/// The captured lines and a signal for each new one.
#[derive(Default)]
struct Capture {
    state: Mutex<Captured>,
    changed: Condvar,
}

impl Capture {
    fn lock(&self) -> MutexGuard<'_, Captured> {
        // A test that failed while waiting leaves the lines as they were.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Reads `from` line by line until end of file (or a read error: the
    /// child is gone either way).
    fn read_lines(self: Arc<Self>, source: Source, from: impl Read) {
        let mut from = BufReader::new(from);
        let mut line = Vec::new();
        loop {
            line.clear();
            match from.read_until(b'\n', &mut line) {
                Ok(0) | Err(_) => break,
                Ok(_) => {
                    let text = String::from_utf8_lossy(&line)
                        .trim_end_matches(['\n', '\r'])
                        .to_string();
                    self.lock().lines.push((source, text));
                    self.changed.notify_all();
                }
            }
        }
        self.lock().open -= 1;
        self.changed.notify_all();
    }
}

/// A child process that is ended, with everything it started, when the
/// guard drops.
pub struct Proc {
    name: String,
    child: Child,
    /// Held open for the child's life: it reads end of file once the test is gone.
    stdin: Option<ChildStdin>,
    output: Arc<Capture>,
    status: Option<ExitStatus>,
}

impl Proc {
    /// Starts `cmd` with its output captured. Call it from the thread that
    /// owns the guard: the kernel's parent-death signal follows the thread
    /// that forked.
    pub fn start(cmd: &mut Command) -> Proc {
        let name = std::iter::once(cmd.get_program())
            .chain(cmd.get_args().take(2))
            .map(|s| {
                let s = std::path::Path::new(s);
                s.file_name().unwrap_or(s.as_os_str()).to_string_lossy().into_owned()
            })
            .collect::<Vec<_>>()
            .join(" ");
        let parent = std::process::id() as libc::pid_t;
        cmd.stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0);
        // SAFETY: the hook runs in the forked child before exec and makes
        // only async-signal-safe system calls (prctl, getppid).
        unsafe {
            cmd.pre_exec(move || {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                // The test died between fork and prctl: do not outlive it.
                if libc::getppid() != parent {
                    return Err(std::io::Error::from_raw_os_error(libc::ESRCH));
                }
                Ok(())
            });
        }
        let mut child = cmd.spawn().unwrap_or_else(|e| panic!("starting {name}: {e}"));
        let output = Arc::new(Capture::default());
        output.lock().open = 2;
        let streams = (child.stdout.take(), child.stderr.take());
        let (Some(stdout), Some(stderr)) = streams else {
            unreachable!("both streams were piped")
        };
        let o = Arc::clone(&output);
        std::thread::spawn(move || o.read_lines(Source::Stdout, stdout));
        let o = Arc::clone(&output);
        std::thread::spawn(move || o.read_lines(Source::Stderr, stderr));
        Proc {
            name,
            stdin: child.stdin.take(),
            child,
            output,
            status: None,
        }
    }

    /// Writes `line` and a newline to the child's standard input.
    #[allow(dead_code)]
    pub fn say(&mut self, line: &str) {
        use std::io::Write as _;
        let stdin = self
            .stdin
            .as_mut()
            .expect("standard input is open until the guard drops");
        writeln!(stdin, "{line}")
            .and_then(|()| stdin.flush())
            .unwrap_or_else(|e| panic!("telling {} {line:?}: {e}\n{}", self.name, self.tail()));
    }

    /// [`Proc::say`] that reports failure instead of failing the test (for
    /// a goodbye said while a test unwinds).
    pub fn try_say(&mut self, line: &str) -> bool {
        use std::io::Write as _;
        self.stdin
            .as_mut()
            .is_some_and(|stdin| writeln!(stdin, "{line}").and_then(|()| stdin.flush()).is_ok())
    }

    /// The child's process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Sends `signal` to the child alone (not its group).
    pub fn signal(&self, signal: libc::c_int) {
        assert!(self.status.is_none(), "{} has already exited", self.name);
        // SAFETY: kill has no memory effects; the child is not reaped, so its
        // PID still names it.
        let rc = unsafe { libc::kill(self.child.id() as libc::pid_t, signal) };
        assert_eq!(rc, 0, "signalling {}: {}", self.name, std::io::Error::last_os_error());
    }

    /// Kills whatever is left of the child's process group. Only called
    /// while the child is not reaped, so its PID (the group's id) is its own.
    fn end_group(&self) {
        // SAFETY: as in `signal`.
        unsafe { libc::kill(-(self.child.id() as libc::pid_t), libc::SIGKILL) };
    }

    /// True once the child has exited; it stays a zombie until reaped.
    fn exited(&self) -> bool {
        // SAFETY: waitid writes only into `info`, which is zeroed first.
        unsafe {
            let mut info: libc::siginfo_t = std::mem::zeroed();
            let rc = libc::waitid(
                libc::P_PID,
                self.child.id(),
                &mut info,
                libc::WEXITED | libc::WNOHANG | libc::WNOWAIT,
            );
            rc == 0 && info.si_pid() != 0
        }
    }

    /// The child's exit status if it has exited; whatever it started and
    /// left behind is killed then.
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() && self.exited() {
            self.end_group();
            let status = self
                .child
                .wait()
                .unwrap_or_else(|e| panic!("reaping {}: {e}", self.name));
            self.status = Some(status);
        }
        self.status
    }

    /// Waits for the child to exit on its own, failing after [`DEADLINE`],
    /// and then briefly for the readers to take in the last of its output
    /// (the reap can come before they have read what it wrote last).
    pub fn wait(&mut self) -> ExitStatus {
        let start = Instant::now();
        loop {
            if let Some(status) = self.try_wait() {
                self.drain(Duration::from_secs(10));
                return status;
            }
            if start.elapsed() >= DEADLINE {
                panic!(
                    "waited {DEADLINE:?} for {} to exit, in vain:\n{}",
                    self.name,
                    self.tail()
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Kills the child (and its group) with SIGKILL and reaps it.
    pub fn kill(&mut self) -> ExitStatus {
        if self.status.is_none() {
            self.end_group();
        }
        self.wait()
    }

    /// Waits up to `limit` for both of the child's output streams to end
    /// (a process it started outside its group may hold them open); true
    /// if they did.
    fn drain(&self, limit: Duration) -> bool {
        let mut state = self.output.lock();
        let start = Instant::now();
        while state.open > 0 {
            let left = limit.saturating_sub(start.elapsed());
            if left.is_zero() {
                return false;
            }
            state = self
                .output
                .changed
                .wait_timeout(state, left)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
        true
    }

    /// Waits for the child to exit and for its output to end; returns both.
    pub fn finish(mut self) -> Output {
        let status = self.wait();
        assert!(self.drain(DEADLINE), "the output of {} never ended", self.name);
        let state = self.output.lock();
        let join = |source: Source| -> Vec<u8> {
            state
                .lines
                .iter()
                .filter(|(s, _)| *s == source)
                .flat_map(|(_, l)| l.bytes().chain(std::iter::once(b'\n')))
                .collect()
        };
        let (stdout, stderr) = (join(Source::Stdout), join(Source::Stderr));
        drop(state);
        Output { status, stdout, stderr }
    }

    /// Lines captured so far: where a later [`Proc::wait_line`] starts to
    /// look for something said after now.
    pub fn mark(&self) -> usize {
        self.output.lock().lines.len()
    }

    /// Waits for a line, from line `*from` on, that `find` answers; leaves
    /// `*from` just past it. Fails when the child's output ends without one,
    /// or after [`DEADLINE`], naming `what` was awaited.
    pub fn wait_line<T>(&self, what: &str, from: &mut usize, mut find: impl FnMut(&str) -> Option<T>) -> T {
        let start = Instant::now();
        let mut state = self.output.lock();
        loop {
            while *from < state.lines.len() {
                let answer = find(&state.lines[*from].1);
                *from += 1;
                if let Some(answer) = answer {
                    return answer;
                }
            }
            if state.open == 0 {
                drop(state);
                panic!("{} stopped talking before {what}:\n{}", self.name, self.tail());
            }
            let left = DEADLINE.saturating_sub(start.elapsed());
            if left.is_zero() {
                drop(state);
                panic!(
                    "waited {DEADLINE:?} for {what} from {}, in vain:\n{}",
                    self.name,
                    self.tail()
                );
            }
            state = self
                .output
                .changed
                .wait_timeout(state, left)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Everything the child printed so far, both streams interleaved.
    pub fn text(&self) -> String {
        let state = self.output.lock();
        state.lines.iter().map(|(_, l)| format!("{l}\n")).collect()
    }

    /// The last lines the child printed, for failure messages.
    fn tail(&self) -> String {
        let state = self.output.lock();
        let skip = state.lines.len().saturating_sub(40);
        state.lines[skip..].iter().map(|(_, l)| format!("  | {l}\n")).collect()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if self.status.is_none() {
            self.end_group();
            let _ = self.child.wait();
        }
        self.stdin.take();
    }
}

/// Runs `cmd` to the end (at most [`DEADLINE`]) and returns what it did.
pub fn run(cmd: &mut Command) -> Output {
    Proc::start(cmd).finish()
}
