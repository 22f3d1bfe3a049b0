//! The `vademecum-bridge` command line (the binary's `main` only calls [`main_entry`]).
//!
//! Parse the arguments, open the device and the channel, run the loop on the main
//! thread until the duration, the end of the device's script, a signal (SIGINT/SIGTERM) or a
//! server timeout, then print the summary and write the trace.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use crate::bridge_loop::{self, AnswerWake, BridgeOutcome, BridgeParams, EndReason};
use crate::device::replay::Replay;
use crate::device::sim::{HandModel, SimStylus};
use crate::device::{Device, NullDevice};
use crate::link::ShmLink;
use crate::profile::{DeviceProfile, FrameMap, Workspace};
use crate::timing::{self, WaitStrategy};
use crate::trajectory::Trajectory;
use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use serde::Serialize;
use vademecum_proto::shm::{self, HapticChannel};

/// The device bridge of vademecum: reads a haptic device at 1 kHz, sends its tool state to a
/// session over shared memory (iceoryx2), and renders the session's force, made safe.
///
/// The server side: a session created with a haptic channel (`vademecum run --haptic NAME`,
/// or `haptic_channel` in CreateSession). The bridge and the server run on the same host as
/// the same user. Either may start first; the bridge waits for the server, fades the force to
/// zero within 4 ticks when the server stops answering, and picks the server up again when it
/// comes back.
///
/// Exit codes: 0 finished (duration, end of script, or a signal); 1 gave up on a silent
/// server (--server-timeout); 2 error.
#[derive(Debug, Parser)]
#[command(name = "vademecum-bridge", version, max_term_width = 100)]
struct Args {
    /// Haptic channel of the session: its id, or the channel name it was created with.
    #[arg(long, value_name = "CHANNEL")]
    session: String,
    /// The scene's tool this bridge moves, in a session whose scene names several (two
    /// devices, two hands: a bridge each): the bridge opens the tool's own channel,
    /// `CHANNEL.NAME` (`SessionInfo.tools[].haptic_channel`). Without it: the session's one
    /// tool.
    #[arg(long, value_name = "NAME")]
    tool_name: Option<String>,
    /// Device driver: `sim` (simulated stylus following --script, pushed back by the force),
    /// `replay` (recorded samples from --script, played as recorded), `null` (a fixed
    /// position).
    #[arg(long, value_enum, default_value_t = DeviceKind::Sim)]
    device: DeviceKind,
    /// CSV `t_s,x_m,y_m,z_m[,closure]`: the hand trajectory for `sim`, the recording for
    /// `replay`. `vademecum run` writes the built-in palpation of a scene as
    /// `out/<scene>/run/trajectory.csv`.
    #[arg(long, value_name = "CSV")]
    script: Option<PathBuf>,
    /// The tool sent to the session: `auto` (a scalpel while the device reports a blade — a
    /// script with the blade columns bx_m,by_m,bz_m,qw,qx,qy,qz — else a probe), `probe`,
    /// `scalpel` or `grasper`. The session clamps the force to the tool's own `max_force`
    /// (SessionInfo.tools), then the bridge to the device profile's limit.
    #[arg(long, value_enum, default_value_t = ToolArg::Auto)]
    tool: ToolArg,
    /// Device profile: its force limit, force-rate limit, speed limit and workspace
    /// (sim, falcon, touch, omega3).
    #[arg(long, default_value = "sim", value_parser = profile_name)]
    profile: String,
    /// Override the profile's force limit (N).
    #[arg(long, allow_negative_numbers = true, value_name = "N")]
    max_force: Option<f64>,
    /// Override the profile's force-rate limit (N/s).
    #[arg(long, allow_negative_numbers = true, value_name = "N_PER_S")]
    max_force_rate: Option<f64>,
    /// Override the profile's hand-speed limit (m/s).
    #[arg(long, allow_negative_numbers = true, value_name = "M_PER_S")]
    max_speed: Option<f64>,
    /// Override the profile's workspace, device frame (m): `xmin,ymin,zmin,xmax,ymax,zmax`.
    #[arg(long, value_name = "BOX", allow_hyphen_values = true, value_parser = numbers::<6>)]
    workspace: Option<[f64; 6]>,
    /// Where the device origin lies in the organ frame (m): `x,y,z`.
    #[arg(long, value_name = "XYZ", allow_hyphen_values = true, value_parser = numbers::<3>, default_value = "0,0,0")]
    origin: [f64; 3],
    /// Motion scaling, organ metres per device metre.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Device newtons per organ newton.
    #[arg(long, default_value_t = 1.0)]
    force_scale: f64,
    /// Loop rate (Hz).
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    rate: f64,
    /// How the loop waits for its deadlines: `sleep` (no CPU, the OS's wake-up jitter),
    /// `spin` (on time, a whole core), `hybrid` (sleep, then spin the last --spin-window-us).
    #[arg(long, default_value = "hybrid")]
    wait: WaitStrategy,
    /// Spin window of the hybrid wait (µs).
    #[arg(long, default_value_t = 200, value_name = "US")]
    spin_window_us: u64,
    /// How long a tick polls for the answer to its own state (µs); 0 renders the newest force
    /// received, one tick late.
    #[arg(long, default_value_t = 300, value_name = "US")]
    answer_wait_us: u64,
    /// How a tick waits for its answer: `poll` the force subscriber (taken microseconds
    /// after it is published; a busy CPU up to --answer-wait-us a tick — one device on its
    /// own core), or block on the server's `event` (no CPU while waiting, a kernel wake-up
    /// per answer — several bridges sharing a host's cores).
    #[arg(long, value_enum, default_value_t = AnswerWake::Poll)]
    answer_wake: AnswerWake,
    /// Stop after this many seconds (default: until the script ends or a signal).
    #[arg(long, value_name = "S")]
    duration: Option<f64>,
    /// Exit (code 1) when no fresh force arrived for this many seconds (default: wait for the
    /// server forever).
    #[arg(long, value_name = "S")]
    server_timeout: Option<f64>,
    /// Say on stderr (once) what to check when no server has opened the channel this many
    /// seconds after the start (another user, a private /tmp or /dev/shm, another channel
    /// name); the bridge goes on waiting.
    #[arg(long, default_value_t = 5.0, value_name = "S", allow_negative_numbers = true)]
    warn_no_server_after: f64,
    /// Write every tick (position sent, force received, force written, freshness) as CSV.
    #[arg(long, value_name = "CSV")]
    record: Option<PathBuf>,
    /// Ticks kept for --record (the first ones).
    #[arg(long, default_value_t = 600_000, value_name = "TICKS")]
    record_limit: usize,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Do not ask for SCHED_FIFO (asked by default, priority --priority, with the sleep and
    /// hybrid waits; refused gracefully when not permitted).
    #[arg(long)]
    no_realtime: bool,
    /// Do not hold the CPU wake-up latency request. By default, while the loop runs, the
    /// bridge asks the kernel (PM QoS, `/dev/cpu_dma_latency`, as cyclictest does) for CPU
    /// wake-ups within 0 µs: idle CPUs poll instead of halting, so a sleeping loop is not
    /// also waiting for a halted vCPU. Refused gracefully without root.
    #[arg(long)]
    no_wake_latency: bool,
    /// SCHED_FIFO priority (1–99).
    #[arg(long, default_value_t = 80, value_parser = clap::value_parser!(i32).range(1..=99))]
    priority: i32,
    /// Pin the loop to this CPU.
    #[arg(long, value_name = "CPU")]
    cpu: Option<usize>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ToolArg {
    Auto,
    Probe,
    Scalpel,
    Grasper,
}

impl ToolArg {
    /// The shared-memory tool kind (`None`: decided by the device's blade).
    fn kind(self) -> Option<u32> {
        match self {
            ToolArg::Auto => None,
            ToolArg::Probe => Some(shm::TOOL_PROBE),
            ToolArg::Scalpel => Some(shm::TOOL_SCALPEL),
            ToolArg::Grasper => Some(shm::TOOL_GRASPER),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum DeviceKind {
    Sim,
    Replay,
    Null,
}

/// `N` comma-separated finite numbers (`--origin x,y,z`, `--workspace xmin,…,zmax`).
fn numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|_| format!("{x:?} is not a number")))
        .collect::<Result<_, _>>()?;
    if v.len() != N || !v.iter().all(|x| x.is_finite()) {
        return Err(format!("expected {N} finite numbers separated by commas, got {s:?}"));
    }
    Ok(std::array::from_fn(|k| v[k]))
}

fn profile_name(s: &str) -> Result<String, String> {
    DeviceProfile::named(s).map(|p| p.name.to_string()).ok_or_else(|| {
        let names: Vec<_> = DeviceProfile::ALL.iter().map(|p| p.name).collect();
        format!("unknown device profile {s:?}: use one of {}", names.join(", "))
    })
}

#[derive(Debug, Serialize)]
struct Summary {
    channel: String,
    device: String,
    profile: String,
    wait: String,
    scheduling: String,
    end: &'static str,
    duration_s: f64,
    ticks: u64,
    deadline_misses: u64,
    fresh_forces: u64,
    watchdog_ticks: u64,
    skipped_forces: u64,
    link_errors: u64,
    latency_us: Quantiles,
    lateness_us: Quantiles,
    rejected_non_finite: u64,
    clamped_jumps: u64,
    clamped_workspace: u64,
    rejected_forces: u64,
    clamped_forces: u64,
    rate_limited_forces: u64,
    cpu_percent: f64,
    /// vCPU steal during the run, % of the machine's CPU time (deadline misses on a VM
    /// follow it: a stolen vCPU runs nothing).
    steal_percent: Option<f64>,
    trace: Option<PathBuf>,
    trace_dropped: u64,
}

#[derive(Debug, Serialize)]
struct Quantiles {
    p50: f64,
    p99: f64,
    p999: f64,
    max: f64,
}

impl Quantiles {
    fn of(h: &hdrhistogram::Histogram<u64>) -> Self {
        let q = |x: f64| if h.is_empty() { 0.0 } else { h.value_at_quantile(x) as f64 / 1e3 };
        Self {
            p50: q(0.5),
            p99: q(0.99),
            p999: q(0.999),
            max: if h.is_empty() { 0.0 } else { h.max() as f64 / 1e3 },
        }
    }
}

fn profile_of(a: &Args) -> anyhow::Result<DeviceProfile> {
    let mut p = DeviceProfile::named(&a.profile).expect("validated by clap");
    if let Some(v) = a.max_force {
        p.max_force_n = v;
    }
    if let Some(v) = a.max_force_rate {
        p.max_force_rate_n_per_s = v;
    }
    if let Some(v) = a.max_speed {
        p.max_speed_m_s = v;
    }
    if let Some(w) = &a.workspace {
        p.workspace = Workspace {
            min_m: [w[0], w[1], w[2]],
            max_m: [w[3], w[4], w[5]],
        };
    }
    p.validate().map_err(|e| anyhow::anyhow!("device profile '{}': {e}", p.name))?;
    Ok(p)
}

fn open_device(a: &Args) -> anyhow::Result<Box<dyn Device>> {
    let script = || {
        a.script.as_ref().ok_or_else(|| {
            anyhow::anyhow!(
                "--device {:?} needs --script CSV (t_s,x_m,y_m,z_m[,closure]); `vademecum run` writes one as out/<scene>/run/trajectory.csv",
                a.device
            )
        })
    };
    Ok(match a.device {
        DeviceKind::Sim => Box::new(SimStylus::new(Trajectory::read(script()?)?, HandModel::default())),
        DeviceKind::Replay => Box::new(Replay::read(script()?)?),
        DeviceKind::Null => Box::new(NullDevice::default()),
    })
}

fn run(a: Args) -> anyhow::Result<ExitCode> {
    if !(a.rate.is_finite() && (10.0..=10_000.0).contains(&a.rate)) {
        bail!("--rate must lie in [10, 10000] Hz, got {}", a.rate);
    }
    if !(a.scale.is_finite() && a.scale > 0.0 && a.force_scale.is_finite() && a.force_scale > 0.0) {
        bail!("--scale and --force-scale must be positive numbers");
    }
    if a.origin.iter().any(|c| !c.is_finite()) {
        bail!("--origin must be three finite numbers (m)");
    }
    let positive = |v: Option<f64>, flag: &str| -> anyhow::Result<Option<Duration>> {
        match v {
            None => Ok(None),
            Some(s) if s.is_finite() && s > 0.0 => Ok(Some(Duration::from_secs_f64(s))),
            Some(s) => bail!("{flag} must be a positive number of seconds, got {s}"),
        }
    };
    let duration = positive(a.duration, "--duration")?;
    let server_timeout = positive(a.server_timeout, "--server-timeout")?;
    let warn_no_server = positive(Some(a.warn_no_server_after), "--warn-no-server-after")?.unwrap_or_default();
    if a.wait == WaitStrategy::Event {
        bail!(
            "--wait event is for a session waiting on its bridge (vademecum run --haptic-wait event); the bridge waits for its deadlines with sleep, spin or hybrid"
        );
    }
    let channel = HapticChannel::new(&a.session)?;
    let channel = match &a.tool_name {
        Some(tool) => channel.for_tool(tool)?,
        None => channel,
    };
    let profile = profile_of(&a)?;
    let mut device = open_device(&a)?;
    if let Some(p) = &a.record
        && let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty())
    {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }

    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, stop.clone()).context("cannot install the signal handlers")?;
    }
    shm::quiet_iceoryx2_logging();
    let mut link = ShmLink::open(&channel)?;
    let fifo = (!a.no_realtime && a.wait != WaitStrategy::Spin).then_some(a.priority);
    let rt = timing::request_realtime(fifo, a.cpu);
    let params = BridgeParams {
        period: Duration::from_secs_f64(1.0 / a.rate),
        strategy: a.wait,
        window: Duration::from_micros(a.spin_window_us),
        answer_wait: Duration::from_micros(a.answer_wait_us),
        answer_wake: a.answer_wake,
        duration,
        server_timeout,
        trace_limit: if a.record.is_some() { a.record_limit } else { 0 },
        profile: profile.clone(),
        frame: FrameMap {
            origin_m: a.origin,
            scale: a.scale,
            force_scale: a.force_scale,
        },
        hold_wake_latency: !a.no_wake_latency,
        tool: a.tool.kind(),
        ..BridgeParams::default()
    };
    eprintln!(
        "vademecum-bridge: channel '{}', device {}, profile {} ({} N, {} N/s), {} Hz, {} wait, {rt}",
        channel.name(),
        device.name(),
        profile.name,
        profile.max_force_n,
        profile.max_force_rate_n_per_s,
        a.rate,
        a.wait
    );
    eprintln!("vademecum-bridge: running (Ctrl-C to stop)");
    // a thread of its own, started after the loop's thread took its real-time policy (which
    // it does not inherit) and stopped with the loop
    let watch = crate::presence::ServerWatch::start(&channel, warn_no_server);
    let out = bridge_loop::run(&mut *device, &mut link, &params, &stop);
    drop(watch);
    let out = out?;
    if let Some(p) = &a.record {
        bridge_loop::write_trace(p, &out.trace).with_context(|| format!("cannot write {}", p.display()))?;
    }
    let summary = summarize(&a, &channel, device.name(), &profile, &rt.to_string(), &out);
    if a.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary);
    }
    Ok(if out.end == EndReason::ServerTimeout {
        eprintln!(
            "vademecum-bridge: no fresh force for {:?}: giving up",
            server_timeout.unwrap_or_default()
        );
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

fn summarize(a: &Args, channel: &HapticChannel, device: &str, profile: &DeviceProfile, rt: &str, out: &BridgeOutcome) -> Summary {
    let r = &out.report;
    Summary {
        channel: channel.name().to_string(),
        device: device.to_string(),
        profile: profile.name.to_string(),
        wait: a.wait.to_string(),
        scheduling: format!("{rt}, {}", out.safeguards()),
        steal_percent: out.steal_percent(std::thread::available_parallelism().map_or(1, |n| n.get())),
        end: match out.end {
            EndReason::Duration => "duration",
            EndReason::DeviceFinished => "end of script",
            EndReason::Stopped => "signal",
            EndReason::ServerTimeout => "server timeout",
        },
        duration_s: out.wall.as_secs_f64(),
        ticks: r.ticks,
        deadline_misses: r.deadline_misses,
        fresh_forces: r.fresh_forces,
        watchdog_ticks: r.watchdog_ticks,
        skipped_forces: out.skipped_forces,
        link_errors: out.link_errors,
        latency_us: Quantiles::of(&out.latency_ns),
        lateness_us: Quantiles::of(&out.lateness_ns),
        rejected_non_finite: r.rejected_non_finite,
        clamped_jumps: r.clamped_jumps,
        clamped_workspace: r.clamped_workspace,
        rejected_forces: r.rejected_forces,
        clamped_forces: r.clamped_forces,
        rate_limited_forces: r.rate_limited_forces,
        cpu_percent: 100.0 * out.cpu.as_secs_f64() / out.wall.as_secs_f64().max(1e-9),
        trace: a.record.clone(),
        trace_dropped: out.trace_dropped,
    }
}

fn print_summary(s: &Summary) {
    let pct = |n: u64| 100.0 * n as f64 / s.ticks.max(1) as f64;
    eprintln!(
        "vademecum-bridge: stopped ({}) after {:.2} s, {} ticks",
        s.end, s.duration_s, s.ticks
    );
    eprintln!(
        "  device read -> force written (fresh forces): p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
        s.latency_us.p50, s.latency_us.p99, s.latency_us.p999, s.latency_us.max
    );
    eprintln!(
        "  deadline misses {} ({:.3} %), fresh forces {} ({:.1} %), watchdog ticks {}, skipped forces {}",
        s.deadline_misses,
        pct(s.deadline_misses),
        s.fresh_forces,
        pct(s.fresh_forces),
        s.watchdog_ticks,
        s.skipped_forces
    );
    eprintln!(
        "  device input: {} non-finite held, {} jumps and {} excursions clamped; forces: {} non-finite, {} clamped, {} slewed",
        s.rejected_non_finite, s.clamped_jumps, s.clamped_workspace, s.rejected_forces, s.clamped_forces, s.rate_limited_forces
    );
    eprintln!("  CPU {:.1} % of a core; {}", s.cpu_percent, s.scheduling);
    if let Some(steal) = s.steal_percent {
        eprintln!("  vCPU steal during the run: {steal:.2} % of the machine's CPU time");
    }
    if let Some(t) = &s.trace {
        eprintln!("  trace: {} ({} ticks not kept)", t.display(), s.trace_dropped);
    }
}

/// Runs the command line of the process and returns its exit code.
pub fn main_entry() -> ExitCode {
    let args = Args::parse();
    match run(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("vademecum-bridge: {e:#}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        Args::command().debug_assert();
    }

    #[test]
    fn sim_and_replay_need_a_script_and_profiles_are_checked() {
        let a = Args::try_parse_from(["b", "--session", "x"]).unwrap();
        assert!(open_device(&a).err().unwrap().to_string().contains("needs --script"));
        assert!(Args::try_parse_from(["b", "--session", "x", "--device", "null"]).is_ok());
        let e = Args::try_parse_from(["b", "--session", "x", "--device", "null", "--profile", "phantom"]).unwrap_err();
        assert!(e.to_string().contains("falcon"), "{e}");
        let a = Args::try_parse_from(["b", "--session", "x", "--device", "null", "--max-force=-1"]).unwrap();
        assert!(profile_of(&a).unwrap_err().to_string().contains("force limit"));
    }

    #[test]
    fn origin_and_workspace_take_comma_separated_numbers_negative_ones_too() {
        let a = Args::try_parse_from([
            "b",
            "--session",
            "x",
            "--origin",
            "-0.1,0.2,-3",
            "--workspace",
            "-20,-20,-20,20,20,20",
        ])
        .unwrap();
        assert_eq!(a.origin, [-0.1, 0.2, -3.0]);
        let p = profile_of(&a).unwrap();
        assert_eq!((p.workspace.min_m, p.workspace.max_m), ([-20.0; 3], [20.0; 3]));
        assert_eq!(Args::try_parse_from(["b", "--session", "x"]).unwrap().origin, [0.0; 3]);
        let a = Args::try_parse_from(["b", "--session", "x", "--tool-name", "left"]).unwrap();
        assert_eq!(a.tool_name.as_deref(), Some("left"));
        for bad in ["1,2", "1,2,3,4", "1,x,3", "1,NaN,3"] {
            let e = Args::try_parse_from(["b", "--session", "x", "--origin", bad]).unwrap_err();
            assert!(
                e.to_string().contains("3 finite numbers") || e.to_string().contains("not a number"),
                "{e}"
            );
        }
        assert!(Args::try_parse_from(["b", "--session", "x", "--workspace", "0,0,0,1,1"]).is_err());
    }
}
