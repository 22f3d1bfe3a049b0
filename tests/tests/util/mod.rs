//! Helpers shared by the end-to-end tests: the real `vademecum` binary, a server process
//! listening on a free port (ready when it prints its address, under a deadline), bundles
//! built once per test folder.

#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{OnceLock, mpsc};
use std::time::Duration;

/// The `vademecum` command line, as this package's own binary (cargo builds it for these
/// tests, with the features of this build).
pub fn vademecum_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_vademecum-under-test"))
}

/// Runs `vademecum args…` in `dir` and returns its output, failing the test on error.
pub fn vademecum(dir: &Path, args: &[&str]) -> std::process::Output {
    let o = Command::new(vademecum_bin())
        .args(args)
        .current_dir(dir)
        .output()
        .expect("vademecum runs");
    assert!(
        o.status.success(),
        "vademecum {args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// A folder holding the built-in organ's bundle as `organ/lobe.bundle`, built once per test
/// run and shared by every test (servers take it as their bundle root).
pub fn bundles() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        vademecum(dir.path(), &["build", "--out", "organ"]);
        dir
    })
    .path()
}

/// A `vademecum serve` process, killed when dropped.
pub struct Server {
    child: Child,
    /// `http://ADDR` of its gRPC endpoint.
    pub url: String,
    /// `ADDR` of its metrics endpoint, if asked.
    pub metrics: Option<String>,
}

impl Server {
    /// Starts `vademecum serve --listen 127.0.0.1:0 extra…` in the shared [`bundles`] folder
    /// with `env`, and waits (at most 120 s) for its "listening on" line.
    pub fn start(extra: &[&str], env: &[(&str, &str)]) -> Self {
        let dir = bundles();
        let mut cmd = Command::new(vademecum_bin());
        cmd.args(["serve", "--listen", "127.0.0.1:0"])
            .args(extra)
            .current_dir(dir)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        for (k, v) in env {
            cmd.env(k, v);
        }
        let mut child = cmd.spawn().expect("server starts");
        let stdout = child.stdout.take().expect("piped stdout");
        let (tx, rx) = mpsc::channel();
        // keep draining stdout for the server's whole life: closing the pipe early would make
        // its next write fail (the broken pipe ends `vademecum` quietly)
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        let (mut url, mut metrics) = (None, None);
        let deadline = std::time::Instant::now() + Duration::from_secs(120);
        while url.is_none() || (extra.contains(&"--metrics") && metrics.is_none()) {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            let line = rx.recv_timeout(left).expect("the server printed its address within 120 s");
            if let Some(a) = line.strip_prefix("listening on ") {
                url = Some(format!("http://{a}"));
            }
            if let Some(a) = line.strip_prefix("metrics on http://") {
                metrics = Some(a.trim_end_matches("/metrics").to_string());
            }
        }
        Self {
            child,
            url: url.expect("address"),
            metrics,
        }
    }

    /// Kills the process now.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.kill();
    }
}

/// A tokio runtime for a test's client side.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime")
}
