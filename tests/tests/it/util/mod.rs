//! Helpers shared by the end-to-end tests: the real `vademecum` binary, a server process
//! listening on a free port (ready when it prints its address, under a deadline), bundles
//! built once per test folder.

#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, OnceLock, mpsc};

use std::time::Duration;

use vademecum_engine::bundle::load_bundle;
use vademecum_engine::pipeline::{Pipeline, ToolInput, ToolKind};
use vademecum_engine::scene::Scene;

/// The `vademecum` command line, as this package's own binary (cargo builds it for these
/// tests, with the features of this build).
pub fn vademecum_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_vademecum-under-test"))
}

/// The scene `text` with keys set by path ([`vademecum_engine::scene::keys::with_keys`]): a
/// path that leads nowhere fails the test (a text replacement would silently do nothing).
pub fn with_keys(text: &str, edits: &[(&str, &str)]) -> String {
    vademecum_engine::scene::keys::with_keys(text, edits).unwrap_or_else(|e| panic!("{e}"))
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

/// A folder holding the built-in organ's bundle as `organ/lobe.bundle` and the built-in
/// `patch_cut` scene's as `patch_cut/patch.bundle` and the built-in `cube_tear` scene's as
/// `cube_tear/cube.bundle`, built once per test run and shared by
/// every test (servers take it as their bundle root).
pub fn bundles() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        vademecum(dir.path(), &["build", "--out", "organ"]);
        vademecum(dir.path(), &["build", "--builtin", "patch_cut", "--out", "patch_cut"]);
        vademecum(dir.path(), &["build", "--builtin", "cube_tear", "--out", "cube_tear"]);
        dir
    })
    .path()
}

/// The built-in organ with a second probe, `left`, beside its own (two hands): its scene text,
/// its bundle built once per test run as `two_probes/lobe.bundle` under [`bundles`].
pub fn two_probes() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| {
        let text = format!(
            "{}\n[[tools]]\nkind = \"probe\"\nname = \"left\"\nradius = 0.004\n",
            vademecum_engine::scene::builtin("organ").unwrap()
        );
        let dir = bundles();
        std::fs::write(dir.join("two_probes.toml"), &text).unwrap();
        vademecum(dir, &["build", "two_probes.toml", "--out", "two_probes"]);
        text
    })
}

/// A `vademecum serve` process, killed when dropped.
pub struct Server {
    child: Child,
    /// `http://ADDR` of its gRPC endpoint.
    pub url: String,
    /// `ADDR` of its metrics endpoint, if asked.
    pub metrics: Option<String>,
    /// `http://ADDR/` of its web viewer, if asked (`--web`).
    pub web: Option<String>,
}

impl Server {
    /// Starts `vademecum serve --listen 127.0.0.1:0 extra…` in the shared [`bundles`] folder
    /// with `env` (and `--no-auth` when neither gives tokens), and waits (at most 120 s) for its "listening on" line.
    pub fn start(extra: &[&str], env: &[(&str, &str)]) -> Self {
        Self::start_at("127.0.0.1:0", extra, env)
    }

    /// [`Server::start`] listening on `listen` (a fleet's servers are given each other's
    /// addresses before they start).
    pub fn start_at(listen: &str, extra: &[&str], env: &[(&str, &str)]) -> Self {
        let dir = bundles();
        let mut cmd = Command::new(vademecum_bin());
        cmd.args(["serve", "--listen", listen])
            .args(extra)
            .current_dir(dir)
            .env_remove("VADEMECUM_TOKENS")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        // a server without tokens must be told so
        if !env.iter().any(|(k, _)| *k == "VADEMECUM_TOKENS") && !extra.contains(&"--tokens-file") {
            cmd.arg("--no-auth");
        }
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
        let (mut url, mut metrics, mut web) = (None, None, None);
        let deadline = std::time::Instant::now() + Duration::from_secs(120);
        while url.is_none() || (extra.contains(&"--metrics") && metrics.is_none()) || (extra.contains(&"--web") && web.is_none()) {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            let line = rx.recv_timeout(left).expect("the server printed its address within 120 s");
            if let Some(a) = line.strip_prefix("listening on ") {
                url = Some(format!("http://{a}"));
            }
            if let Some(a) = line.strip_prefix("metrics on http://") {
                metrics = Some(a.trim_end_matches("/metrics").to_string());
            }
            if let Some(a) = line.strip_prefix("web viewer on ") {
                web = Some(a.to_string());
            }
        }
        Self {
            child,
            url: url.expect("address"),
            metrics,
            web,
        }
    }

    /// The names of the server's threads (Linux: `/proc/PID/task/*/comm`, 15 characters).
    pub fn threads(&self) -> Vec<String> {
        threads_of(&self.child)
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

/// The device bridge command line, as this package's own binary.
pub fn bridge_bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_bridge-under-test"))
}

/// A unique haptic channel name for one test.
pub fn channel(test: &str) -> String {
    format!("t{}-{test}", std::process::id())
}

/// A `vademecum run --haptic CHANNEL` process on the built-in organ (its bundle from
/// [`bundles`]), recording into `record`; killed when dropped.
pub struct HapticRun {
    /// The process.
    pub child: Child,
}

/// The names of a process's threads (`/proc/PID/task/*/comm`).
pub fn threads_of(child: &Child) -> Vec<String> {
    let dir = format!("/proc/{}/task", child.id());
    std::fs::read_dir(dir)
        .map(|d| {
            d.filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
                .map(|n| n.trim().to_string())
                .collect()
        })
        .unwrap_or_default()
}

impl HapticRun {
    /// Starts it on the built-in organ and waits (at most 120 s) for its "haptic channel …
    /// open" line.
    pub fn start(channel: &str, record: &Path, extra: &[&str]) -> Self {
        Self::start_with("organ", channel, record, extra)
    }

    /// [`start`](Self::start) with the bundles of folder `bundles` (of [`bundles`]; `extra`
    /// names the scene when it is not the organ).
    pub fn start_with(bundles_dir: &str, channel: &str, record: &Path, extra: &[&str]) -> Self {
        let mut child = Command::new(vademecum_bin())
            .args(["run", "--bundles", bundles_dir, "--haptic", channel, "--record"])
            .arg(record)
            .args(extra)
            .current_dir(bundles())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("vademecum run starts");
        let stderr = child.stderr.take().expect("piped stderr");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        let deadline = std::time::Instant::now() + Duration::from_secs(120);
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match rx.recv_timeout(left) {
                Ok(l) if l.contains("haptic channel") && l.contains("open") => break,
                Ok(_) => {}
                Err(_) => {
                    let _ = child.kill();
                    panic!("vademecum run --haptic did not open its channel within 120 s");
                }
            }
        }
        // keep draining its stderr
        std::thread::spawn(move || while rx.recv().is_ok() {});
        Self { child }
    }

    /// Stops it as an operator would (SIGTERM: it ends its session and writes its summary)
    /// and waits for it to exit.
    pub fn stop(mut self) -> std::process::ExitStatus {
        let _ = Command::new("kill").args(["-TERM", &self.child.id().to_string()]).status();
        self.child.wait().expect("vademecum run exits")
    }

    /// Kills it at once (SIGKILL: a crash, leaving its shared memory behind).
    pub fn crash(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for HapticRun {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One row of a bridge trace (`--record`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    pub tick: u64,
    pub position_m: [f64; 3],
    pub fresh: bool,
    pub answers: Option<u64>,
    pub received_n: [f64; 3],
    pub output_n: [f64; 3],
    pub input_adjusted: bool,
}

/// Reads a bridge trace.
pub fn read_trace(path: &Path) -> Vec<TraceRow> {
    let text = std::fs::read_to_string(path).expect("trace written");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (tick, x, fresh, answers, fx, ox, adj) = (
        col("tick"),
        col("x_m"),
        col("fresh"),
        col("answers"),
        col("fx_n"),
        col("out_x_n"),
        col("input_adjusted"),
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let num = |i: usize| f[i].parse::<f64>().expect("number");
            TraceRow {
                tick: f[tick].parse().expect("tick"),
                position_m: [num(x), num(x + 1), num(x + 2)],
                fresh: f[fresh] == "1",
                answers: f[answers].parse().ok(),
                received_n: [num(fx), num(fx + 1), num(fx + 2)],
                output_n: [num(ox), num(ox + 1), num(ox + 2)],
                input_adjusted: f[adj] == "1",
            }
        })
        .collect()
}

/// The engine's force for each position, evaluated in this process from the same bundle.
pub fn engine() -> Pipeline {
    let scene = Scene::builtin("organ").unwrap();
    let bundle = Arc::new(load_bundle(&bundles().join("organ/lobe.bundle")).unwrap());
    Pipeline::for_scene(&scene, &[bundle]).unwrap()
}

pub fn force_at(p: &mut Pipeline, x: [f64; 3]) -> [f64; 3] {
    p.tick(&ToolInput {
        kind: ToolKind::Probe,
        position_m: x,
        ..ToolInput::default()
    })
    .force_n
}

pub fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Every fresh force in `rows[range]` equals the engine's force at the position it answers
/// (a position sent at most a few ticks earlier).
pub fn assert_forces_match_engine(rows: &[TraceRow], range: std::ops::Range<usize>, engine: &mut Pipeline) -> usize {
    // each replay is of a session of its own: no contact carried over from the last one
    engine.reset();
    let first = rows[0].tick;
    let mut touching = 0;
    for r in rows[range].iter().filter(|r| r.fresh) {
        let answered = r.answers.expect("a fresh force answers a state");
        let asked = rows[(answered - first) as usize];
        assert_eq!(asked.tick, answered);
        let want = force_at(engine, asked.position_m);
        let err = norm([0, 1, 2].map(|k| r.received_n[k] - want[k]));
        assert!(
            err <= 1e-9 * (1.0 + norm(want)),
            "tick {}: the server sent {:?} for the position of tick {answered}, the engine gives {want:?}",
            r.tick,
            r.received_n
        );
        touching += usize::from(norm(want) > 0.05);
    }
    touching
}
