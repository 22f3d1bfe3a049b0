//! `vademecum bench effects`: what each effect costs, scene by scene — build time, bundle size
//! on disk, the session's own memory by effect and its tick work — by running `vademecum
//! build` and `vademecum run --json` of this binary in child processes, one scene at a time.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::Instant;

use anyhow::{Context, bail};
use serde::Serialize;

use crate::cli::BenchEffectsArgs;

/// The default scenes: the cornea with each effect added to palpation, then two of them
/// composed on it (large deformations and cutting).
const DEFAULT_SCENES: [&str; 5] = [
    "scenes/effects/cornea_palpation.toml",
    "scenes/effects/cornea_large.toml",
    "scenes/effects/cornea_cutting.toml",
    "scenes/effects/cornea_tearing.toml",
    "scenes/effects/cornea_large_cutting.toml",
];

/// One scene's costs.
#[derive(Debug, Serialize)]
struct Row {
    scene: String,
    effects: Vec<String>,
    build_s: f64,
    bundle_bytes: u64,
    /// The session's own memory (bytes), all parts, and by effect.
    session_bytes: u64,
    effect_bytes: Vec<(String, u64)>,
    ticks: u64,
    tick_work_p50_us: f64,
    tick_work_p99_us: f64,
    tick_work_p999_us: f64,
    miss_rate: f64,
}

/// Bytes of every file under `dir`.
pub(super) fn dir_bytes(dir: &Path) -> std::io::Result<u64> {
    let mut total = 0;
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let m = e.metadata()?;
        total += if m.is_dir() { dir_bytes(&e.path())? } else { m.len() };
    }
    Ok(total)
}

/// Runs this binary with `args`; its stdout, or its stderr as the error.
fn child(args: &[&std::ffi::OsStr]) -> anyhow::Result<Vec<u8>> {
    let exe = std::env::current_exe().context("locating this binary")?;
    let o = Command::new(exe).args(args).output().context("starting a child vademecum")?;
    if !o.status.success() {
        bail!(
            "`vademecum {}` failed: {}",
            args.iter().map(|a| a.to_string_lossy()).collect::<Vec<_>>().join(" "),
            String::from_utf8_lossy(&o.stderr).trim()
        );
    }
    Ok(o.stdout)
}

fn measure(scene: &Path, work: &Path, seconds: Option<f64>) -> anyhow::Result<Row> {
    let bundles = work.join("bundles");
    let record = work.join("record");
    let start = Instant::now();
    child(&["build".as_ref(), scene.as_os_str(), "--out".as_ref(), bundles.as_os_str()])?;
    let build_s = start.elapsed().as_secs_f64();
    let bundle_bytes = dir_bytes(&bundles)?;
    let duration = seconds.map(|s| s.to_string());
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "run".as_ref(),
        scene.as_os_str(),
        "--bundles".as_ref(),
        bundles.as_os_str(),
        "--record".as_ref(),
        record.as_os_str(),
        "--json".as_ref(),
    ];
    if let Some(d) = &duration {
        args.push("--duration".as_ref());
        args.push(d.as_ref());
    }
    let s: serde_json::Value = serde_json::from_slice(&child(&args)?).context("reading the run's JSON summary")?;
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let parts = s["memory"]["parts"].as_array().cloned().unwrap_or_default();
    let part = |p: &serde_json::Value| (p[0].as_str().unwrap_or("").to_string(), p[1].as_u64().unwrap_or(0));
    Ok(Row {
        scene: scene.display().to_string(),
        effects: s["effects"]
            .as_array()
            .map(|a| a.iter().filter_map(|e| e.as_str().map(String::from)).collect())
            .unwrap_or_default(),
        build_s,
        bundle_bytes,
        session_bytes: parts.iter().map(|p| part(p).1).sum(),
        effect_bytes: parts.iter().map(part).filter(|(n, _)| n.starts_with("effect:")).collect(),
        ticks: s["ticks"].as_u64().unwrap_or(0),
        tick_work_p50_us: num(&s["tick_work_us"]["p50"]),
        tick_work_p99_us: num(&s["tick_work_us"]["p99"]),
        tick_work_p999_us: num(&s["tick_work_us"]["p999"]),
        miss_rate: num(&s["miss_rate"]),
    })
}

/// Builds and runs every scene and prints the table.
pub fn run(a: BenchEffectsArgs) -> anyhow::Result<ExitCode> {
    let scenes: Vec<PathBuf> = if a.scenes.is_empty() {
        DEFAULT_SCENES.iter().map(PathBuf::from).collect()
    } else {
        a.scenes.clone()
    };
    if let Some(missing) = scenes.iter().find(|s| !s.is_file()) {
        bail!(
            "no scene at {} (the default scenes are in the repository's scenes/effects/: run from the repository's folder, or name your scenes)",
            missing.display()
        );
    }
    let temp = tempfile::tempdir()?;
    let root = a.out.clone().unwrap_or_else(|| temp.path().to_path_buf());
    let stages = crate::progress::Stages::start("bench effects");
    let mut rows = Vec::new();
    for (i, scene) in scenes.iter().enumerate() {
        stages.stage(&format!("{} ({} of {}): build, then run", scene.display(), i + 1, scenes.len()));
        let work = root.join(format!("{i}"));
        std::fs::create_dir_all(&work)?;
        rows.push(measure(scene, &work, a.seconds)?);
    }
    stages.finish();
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&rows)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    writeln!(
        out,
        "| scene | effects | build (s) | bundle (MB) | session (MiB) | of which effects (MiB) | tick work p50 / p99 / p99.9 (µs) | misses |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|---|---|")?;
    let mib = |b: u64| b as f64 / 1048576.0;
    for r in &rows {
        let name = Path::new(&r.scene)
            .file_stem()
            .map_or(r.scene.clone(), |s| s.to_string_lossy().into_owned());
        writeln!(
            out,
            "| {name} | {} | {:.1} | {:.2} | {:.2} | {} | {:.1} / {:.1} / {:.1} | {:.2} % |",
            r.effects.join(" + "),
            r.build_s,
            r.bundle_bytes as f64 / 1e6,
            mib(r.session_bytes),
            r.effect_bytes
                .iter()
                .map(|(n, b)| format!("{} {:.2}", n.trim_start_matches("effect:"), mib(*b)))
                .collect::<Vec<_>>()
                .join(", "),
            r.tick_work_p50_us,
            r.tick_work_p99_us,
            r.tick_work_p999_us,
            100.0 * r.miss_rate
        )?;
    }
    if let Some(base) = rows.first() {
        writeln!(out, "\nAgainst {} (the baseline):", base.scene)?;
        for r in &rows[1..] {
            writeln!(
                out,
                "  {}: build {:+.1} s, bundle {:+.2} MB, session {:+.2} MiB, tick work p50 {:+.1} µs, p99 {:+.1} µs",
                r.scene,
                r.build_s - base.build_s,
                (r.bundle_bytes as f64 - base.bundle_bytes as f64) / 1e6,
                (r.session_bytes as f64 - base.session_bytes as f64) / 1048576.0,
                r.tick_work_p50_us - base.tick_work_p50_us,
                r.tick_work_p99_us - base.tick_work_p99_us
            )?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
