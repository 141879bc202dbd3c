//! A real browser for the web display's tests: Debian's chromium, headless,
//! driven by Playwright (`tests/web/drive.mjs`, node) pointed at the system
//! browser; nothing downloads a browser. Each request is a JSON line on the
//! driver's standard input, each answer a JSON line on its standard output,
//! awaited under the tests' one deadline.
//!
//! Where chromium or playwright-core is missing the tests say so and pass,
//! unless `HOLODECK_BROWSER_TESTS=required` (as CI sets it, having installed
//! both), where that is a failure.

use std::path::{Path, PathBuf};
use std::process::Command;

use holodeck_protocol::Picture;
use serde_json::{json, Value};

use crate::common::process::Proc;

/// A browser with one page, driven by requests.
pub struct Browser {
    driver: Proc,
    from: usize,
    /// The browser's process: Playwright starts it in a process group of
    /// its own, which this guard ends by its PID.
    pid: i32,
}

/// The folder of the browser driver and its node modules.
fn driver_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("web")
}

impl Browser {
    /// Starts the browser, or says why it cannot (and fails where the
    /// browser tests are required).
    pub fn start() -> Option<Browser> {
        Browser::start_with(&[])
    }

    /// [`Browser::start`] with more of chromium's flags.
    pub fn start_with(flags: &[&str]) -> Option<Browser> {
        let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
        let dir = driver_dir();
        let node = Command::new("node")
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success());
        let missing = if !Path::new(&chromium).exists() {
            Some(format!("there is no browser at {chromium} (apt-get install chromium)"))
        } else if !node {
            Some("there is no node (apt-get install nodejs)".to_string())
        } else if !dir.join("node_modules").join("playwright-core").exists() {
            Some(format!(
                "playwright-core is not installed in {} (npm ci there)",
                dir.display()
            ))
        } else {
            None
        };
        if let Some(why) = missing {
            if std::env::var("HOLODECK_BROWSER_TESTS").is_ok_and(|v| v == "required") {
                panic!("the browser tests are required here, but {why}");
            }
            eprintln!("browser test skipped: {why}");
            return None;
        }
        let driver = Proc::start(
            Command::new("node")
                .arg("drive.mjs")
                .current_dir(&dir)
                .env("CHROMIUM", chromium)
                .env("CHROMIUM_FLAGS", flags.join(" ")),
        );
        let mut from = 0;
        let pid = driver.wait_line("the browser's process id", &mut from, |l| {
            serde_json::from_str::<Value>(l).ok()?.get("browser_pid")?.as_i64()
        }) as i32;
        Some(Browser { driver, from, pid })
    }

    /// Sends `request`; its answer's value (fails the test on an error).
    pub fn ask(&mut self, request: Value) -> Value {
        self.driver.say(&request.to_string());
        let answer: Value = self
            .driver
            .wait_line(&format!("the answer to {request}"), &mut self.from, |l| {
                l.starts_with('{').then(|| serde_json::from_str(l).ok()).flatten()
            });
        if let Some(e) = answer.get("error") {
            let console = self.console();
            panic!("the browser failed {request}: {e}\nthe page's console:\n{console}");
        }
        answer["ok"].clone()
    }

    /// Opens `url`.
    pub fn open(&mut self, url: &str) {
        self.ask(json!({"op": "open", "url": url}));
    }

    /// The value of the JavaScript expression `js` in the page.
    pub fn eval(&mut self, js: &str) -> Value {
        self.ask(json!({"op": "eval", "js": js}))
    }

    /// Waits until `js` is truthy in the page; its value.
    pub fn wait(&mut self, js: &str) -> Value {
        self.ask(json!({"op": "wait", "js": js, "timeout": 100_000}))
    }

    /// What the page logged to its console.
    pub fn console(&mut self) -> String {
        self.driver.say(&json!({"op": "console"}).to_string());
        let answer: Value = self.driver.wait_line("the console", &mut self.from, |l| {
            l.starts_with('{').then(|| serde_json::from_str(l).ok()).flatten()
        });
        answer["ok"]
            .as_array()
            .map(|a| a.iter().filter_map(Value::as_str).collect::<Vec<_>>().join("\n"))
            .unwrap_or_default()
    }

    /// The page's picture in linear radiance (`holodeck.picture()`).
    pub fn picture(&mut self) -> Picture {
        let p = self.eval("holodeck.picture()");
        let (width, height) = (
            p["width"].as_u64().unwrap() as usize,
            p["height"].as_u64().unwrap() as usize,
        );
        let data: Vec<f32> = p["data"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap() as f32)
            .collect();
        assert_eq!(data.len(), width * height * 3);
        Picture {
            width,
            height,
            pixels: data
                .chunks_exact(3)
                .map(|c| glam::Vec3::new(c[0], c[1], c[2]))
                .collect(),
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        // The driver closes the browser if it can; the browser's process
        // group is ended by its PID whatever happened, and the driver's by
        // its guard.
        self.driver.try_say(&json!({"op": "close"}).to_string());
        // SAFETY: kill(2) with a PID this guard's driver reported.
        unsafe {
            libc::kill(-self.pid, libc::SIGKILL);
            libc::kill(self.pid, libc::SIGKILL);
        }
    }
}
