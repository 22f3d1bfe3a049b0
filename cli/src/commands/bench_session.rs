//! `vademecum bench session`: real-time behaviour of sessions on this machine, each figure
//! beside a null loop measured in the same run (a thread sleeping to the same 1 ms
//! deadlines and doing nothing), so the OS wake-up floor and our overhead are told apart.
//!
//! 1. null loop; 2. a session's ticks with no viewer, then 3. with two 30 Hz viewers and one
//!    5 Hz viewer; 4. the gRPC round trip on loopback at 1 kHz (a client sends a tool state
//!    every millisecond and waits for its answer), beside tonic's echo of the same stream;
//!    5. N concurrent sessions, each playing the built-in palpation, with a thread each and
//!    on the tick workers (one per CPU): deadline misses per N.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use hdrhistogram::Histogram;
use serde::Serialize;
use vademecum_client::pb;
use vademecum_engine::scene::Scene;
use vademecum_server::session::stats::Percentiles;
use vademecum_server::session::{SchedulerConfig, Script, Session, SessionConfig, TickScheduler, ToolCommand};

use crate::cli::BenchSessionArgs;
use crate::commands::build::ensure_bundles;

#[derive(Debug, Serialize)]
struct Row {
    what: String,
    samples: u64,
    p50_us: f64,
    p99_us: f64,
    p999_us: f64,
    max_us: f64,
    misses: u64,
}

fn row(what: impl Into<String>, p: Percentiles, misses: u64) -> Row {
    Row {
        what: what.into(),
        samples: p.count,
        p50_us: p.p50,
        p99_us: p.p99,
        p999_us: p.p999,
        max_us: p.max,
        misses,
    }
}

pub(super) fn hist() -> Histogram<u64> {
    Histogram::new_with_bounds(1, 10_000_000_000, 3).expect("valid bounds")
}

/// The null loop: sleep to 1 ms deadlines for `secs`, recording lateness (ns).
fn null_loop(secs: f64) -> (Percentiles, u64) {
    let end = Instant::now() + Duration::from_secs_f64(secs);
    let (p, misses, _) = null_loop_while(|| Instant::now() < end, &NullCounts::default());
    (p, misses)
}

/// A null loop's ticks and misses so far, for a reader sampling them while it runs.
#[derive(Debug, Default)]
pub(super) struct NullCounts {
    pub ticks: std::sync::atomic::AtomicU64,
    pub misses: std::sync::atomic::AtomicU64,
}

/// The null loop until `stop` is set, publishing its counts in `counts`: its lateness (ns),
/// misses and ticks.
pub(super) fn null_loop_until(stop: &std::sync::atomic::AtomicBool, counts: &NullCounts) -> (Percentiles, u64, u64) {
    null_loop_while(|| !stop.load(std::sync::atomic::Ordering::Relaxed), counts)
}

/// Sleeps to 1 ms deadlines while `going()`, recording lateness (ns): its percentiles, its
/// misses (a tick more than a period late) and its ticks.
fn null_loop_while(going: impl Fn() -> bool, counts: &NullCounts) -> (Percentiles, u64, u64) {
    let period = Duration::from_millis(1);
    let mut h = hist();
    let (mut misses, mut ticks) = (0, 0);
    let mut next = Instant::now() + period;
    while going() {
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        }
        let late = Instant::now().saturating_duration_since(next);
        let _ = h.record((late.as_nanos() as u64).max(1));
        ticks += 1;
        if late > period {
            misses += 1;
        }
        counts.ticks.store(ticks, std::sync::atomic::Ordering::Relaxed);
        counts.misses.store(misses, std::sync::atomic::Ordering::Relaxed);
        next += period;
        if Instant::now() > next + period * 10 {
            next = Instant::now();
        }
    }
    (Percentiles::of(&h), misses, ticks)
}

pub fn run(a: BenchSessionArgs) -> anyhow::Result<ExitCode> {
    if !(a.seconds > 0.0 && a.seconds <= 600.0) {
        bail!("--seconds must lie in (0, 600], got {}", a.seconds);
    }
    let scene = Arc::new(Scene::builtin("organ")?);
    let dir = a.bundles.clone().unwrap_or_else(|| PathBuf::from("out/organ"));
    let bundles = ensure_bundles(&scene, &dir)?;
    let traj = vademecum_server::session::builtin_palpation(&bundles[0], 0.004, 0.004, 0.015).map_err(anyhow::Error::msg)?;
    let mut rows = Vec::new();
    let (p, m) = null_loop(a.seconds);
    rows.push(row("null loop: lateness of a 1 ms sleep, no work", p, m));
    // a session fed at 1 kHz by a thread, with and without viewers
    for viewers in [0usize, 3] {
        let s = Session::start(format!("bench{viewers}"), scene.clone(), bundles.clone(), SessionConfig::default())?;
        let mut rx = Vec::new();
        for k in 0..viewers {
            let mut f = s.subscribe_frames();
            let rate = if k < 2 { 30.0 } else { 5.0 };
            rx.push(std::thread::spawn(move || {
                let mut n = 0u64;
                let end = Instant::now() + Duration::from_secs_f64(a.seconds);
                while Instant::now() < end {
                    std::thread::sleep(Duration::from_secs_f64(1.0 / rate));
                    if f.has_changed().unwrap_or(false) {
                        let frame = f.borrow_and_update().clone();
                        n += u64::from(!frame.displacements_m.is_empty());
                    }
                }
                n
            }));
        }
        let mut answers = s.open_answers(1024)?;
        let end = Instant::now() + Duration::from_secs_f64(a.seconds);
        let mut i = 0u64;
        while Instant::now() < end {
            let t = (i % 5000) as f64 * 1e-3;
            let _ = s.submit(ToolCommand {
                input: vademecum_server::session::tool_at(&traj, t),
                seq: i,
                client_time_us: 0,
                received: Instant::now(),
                reply: answers.id(),
                named: false,
            });
            while answers.try_recv().is_ok() {}
            i += 1;
            std::thread::sleep(Duration::from_millis(1));
        }
        let frames: u64 = rx.into_iter().map(|h| h.join().unwrap_or(0)).sum();
        let st = s.close();
        let label = if viewers == 0 {
            "no viewer".to_string()
        } else {
            format!("{viewers} viewers (2 × 30 Hz, 5 Hz; {frames} frames taken)")
        };
        rows.push(row(format!("session tick work, {label}"), st.work_us, st.misses));
        rows.push(row(format!("session tick lateness, {label}"), st.lateness_us, st.misses));
        rows.push(row(
            format!("tool state in → answer out, inside the session, {label}"),
            st.response_us,
            0,
        ));
    }
    // gRPC round trip on loopback at 1 kHz
    let (rtt, echo) = grpc_round_trip(&dir, a.seconds)?;
    rows.push(row(
        "gRPC round trip on loopback, 1 tool state per ms (client send → response received)",
        rtt,
        0,
    ));
    rows.push(row(
        "… tonic echo on loopback, same stream and pacing (no session behind it)",
        echo,
        0,
    ));
    // concurrent scripted sessions: a thread each, then on the tick workers
    let workers = Arc::new(TickScheduler::new(SchedulerConfig::default())?);
    for n in a.concurrent.iter().copied() {
        let (p, m) = null_loop(a.seconds.min(5.0));
        rows.push(row(format!("null loop before {n} concurrent sessions"), p, m));
        for ticking in [None, Some(workers.clone())] {
            let how = match &ticking {
                None => "a thread each".to_string(),
                Some(w) => format!("on {} tick workers", w.config().workers),
            };
            let (work, late, misses, cores) = concurrent(n, &scene, &bundles, &traj, ticking)?;
            rows.push(row(
                format!("{n} concurrent sessions, {how} (5 s palpation each; process CPU {cores:.2} cores): tick work"),
                work,
                misses,
            ));
            rows.push(row(format!("{n} concurrent sessions, {how}: tick lateness"), late, misses));
        }
    }
    super::bench::print_rows(
        a.json,
        &rows,
        &[
            "what",
            "samples",
            "p50 (µs)",
            "p99 (µs)",
            "p99.9 (µs)",
            "max (µs)",
            "deadline misses",
        ],
        |r| {
            vec![
                r.what.clone(),
                r.samples.to_string(),
                format!("{:.1}", r.p50_us),
                format!("{:.1}", r.p99_us),
                format!("{:.1}", r.p999_us),
                format!("{:.1}", r.max_us),
                r.misses.to_string(),
            ]
        },
    )?;
    Ok(ExitCode::SUCCESS)
}

/// `n` sessions each playing `traj` at once, ticked by `ticking` (`None`: a thread each):
/// their tick work and lateness, their deadline misses, and the process's CPU time over the
/// run in cores (every thread: ticks, answer dispatchers, frame threads, the answers' readers).
fn concurrent(
    n: usize,
    scene: &Arc<Scene>,
    bundles: &[Arc<vademecum_engine::bundle::LoadedBundle>],
    traj: &vademecum_server::session::Trajectory,
    ticking: Option<Arc<TickScheduler>>,
) -> anyhow::Result<(Percentiles, Percentiles, u64, f64)> {
    let (wall, cpu) = (Instant::now(), vademecum_bridge::timing::process_cpu_time());
    let mut sessions = Vec::new();
    for k in 0..n {
        let (tx, mut rx) = tokio::sync::mpsc::channel(16384);
        std::thread::spawn(move || while rx.blocking_recv().is_some() {});
        sessions.push(Session::start_scripted(
            format!("c{k}"),
            scene.clone(),
            bundles.to_vec(),
            SessionConfig {
                ticking: ticking.clone(),
                ..SessionConfig::default()
            },
            Script::new(traj.clone(), tx),
        )?);
    }
    let mut work = hist();
    let mut late = hist();
    let mut misses = 0;
    for s in sessions {
        let st = s.stats().clone();
        let _ = s.wait();
        let h = st.histograms();
        let _ = work.add(&h.work);
        let _ = late.add(&h.lateness);
        misses += st.misses.load(std::sync::atomic::Ordering::Relaxed);
    }
    let cores = (vademecum_bridge::timing::process_cpu_time() - cpu).as_secs_f64() / wall.elapsed().as_secs_f64();
    Ok((Percentiles::of(&work), Percentiles::of(&late), misses, cores))
}

/// The tool state sent `i`-th: a circle over the organ, pressing in and out.
pub(super) fn bench_tool(i: u64) -> vademecum_client::pb::ToolState {
    vademecum_client::tool_at(i, bench_path(i))
}

/// Where the benchmarks' probe is at its `i`-th state (1 ms apart): circles over the built-in
/// organ, pressing in and out, repeating every 5 s.
pub(super) fn bench_path(i: u64) -> [f64; 3] {
    let s = (i % 5000) as f64 * 1e-3;
    [
        0.02 * (3.0 * s).cos(),
        0.015 * (3.0 * s).sin(),
        0.030 - 0.006 * (5.0 * s).sin().abs(),
    ]
}

/// Calls `round_trip(i)` once per millisecond (paced by sleeping to deadlines) for `secs`,
/// timing each call (ns).
async fn paced(secs: f64, mut round_trip: impl AsyncFnMut(u64) -> anyhow::Result<()>) -> anyhow::Result<Percentiles> {
    let mut h = hist();
    let period = Duration::from_millis(1);
    let end = Instant::now() + Duration::from_secs_f64(secs);
    let mut next = Instant::now();
    let mut i = 0u64;
    while Instant::now() < end {
        let now = Instant::now();
        if next > now {
            tokio::time::sleep(next - now).await;
        }
        let t0 = Instant::now();
        round_trip(i).await?;
        let _ = h.record((t0.elapsed().as_nanos() as u64).max(1));
        i += 1;
        next += period;
        if Instant::now() > next + period * 10 {
            next = Instant::now();
        }
    }
    Ok(Percentiles::of(&h))
}

/// A server in this process on a free loopback port, and a client sending one tool state
/// per millisecond and waiting for its answer; then, in the same runtime, the same stream
/// against tonic's echo ([`Echo`]): the floor of a gRPC round trip on this host.
fn grpc_round_trip(bundle_dir: &std::path::Path, secs: f64) -> anyhow::Result<(Percentiles, Percentiles)> {
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    rt.block_on(async {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
        let addr = listener.local_addr()?;
        let parent = bundle_dir.parent().map(PathBuf::from).unwrap_or_else(|| PathBuf::from("."));
        let name = bundle_dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let config = vademecum_server::config::ServerConfig {
            bundle_root: parent,
            ..Default::default()
        };
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let server = tokio::spawn(vademecum_server::run(listener, None, None, config, async {
            let _ = stop_rx.await;
        }));
        let client = vademecum_client::Client::connect(format!("http://{addr}")).await?;
        let session = client
            .create_session(vademecum_client::SceneSpec::Builtin("organ".into()), &name, "bench")
            .await?;
        let mut tools = session.interact().await?;
        let session_rtt = paced(secs, async |i| {
            tools.send(bench_tool(i)).await?;
            let r = tools.next().await?.context("the server ended the stream")?;
            anyhow::ensure!(r.seq == i, "answer {} for tool state {i}", r.seq);
            Ok(())
        })
        .await?;
        tools.finish();
        let _ = session.close().await;
        let _ = stop_tx.send(());
        let _ = server.await;
        let echo_rtt = echo_round_trip(secs).await?;
        Ok((session_rtt, echo_rtt))
    })
}

/// tonic's floor: an `Interaction` service that answers each tool state at once with its
/// sequence number, no session behind it — the same stream shape as the real service (a task
/// per stream forwarding through a bounded channel).
#[derive(Debug, Clone, Copy)]
pub(super) struct Echo;

type EchoStream = std::pin::Pin<Box<dyn tokio_stream::Stream<Item = Result<pb::ToolResponse, tonic::Status>> + Send>>;

#[tonic::async_trait]
impl pb::interaction_server::Interaction for Echo {
    type InteractStream = EchoStream;

    async fn interact(
        &self,
        req: tonic::Request<tonic::Streaming<pb::ToolState>>,
    ) -> Result<tonic::Response<Self::InteractStream>, tonic::Status> {
        let mut inbound = req.into_inner();
        let (out, rx) = tokio::sync::mpsc::channel(256);
        tokio::spawn(async move {
            while let Ok(Some(m)) = inbound.message().await {
                let r = pb::ToolResponse {
                    seq: m.seq,
                    client_time_us: m.client_time_us,
                    ..Default::default()
                };
                if out.send(Ok(r)).await.is_err() {
                    break;
                }
            }
        });
        Ok(tonic::Response::new(Box::pin(tokio_stream::wrappers::ReceiverStream::new(rx))))
    }
}

/// [`Echo`] served on a free loopback port in this runtime.
pub(super) struct EchoServer {
    /// Its URL.
    pub url: String,
    stop: tokio::sync::oneshot::Sender<()>,
    task: tokio::task::JoinHandle<Result<(), tonic::transport::Error>>,
}

impl EchoServer {
    pub async fn start() -> anyhow::Result<Self> {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
        let url = format!("http://{}", listener.local_addr()?);
        let (stop, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let task = tokio::spawn(
            tonic::transport::Server::builder()
                .add_service(pb::interaction_server::InteractionServer::new(Echo))
                .serve_with_incoming_shutdown(vademecum_server::incoming(listener), async {
                    let _ = stop_rx.await;
                }),
        );
        Ok(Self { url, stop, task })
    }

    /// An interaction stream to it, its first state (sequence 0) already echoed: send the
    /// next from sequence 1.
    pub async fn stream(&self) -> anyhow::Result<(tokio::sync::mpsc::Sender<pb::ToolState>, tonic::Streaming<pb::ToolResponse>)> {
        let mut client = pb::interaction_client::InteractionClient::connect(self.url.clone()).await?;
        let (tx, rx) = tokio::sync::mpsc::channel(16);
        tx.send(bench_tool(0)).await?;
        let mut responses = client.interact(tokio_stream::wrappers::ReceiverStream::new(rx)).await?.into_inner();
        anyhow::ensure!(responses.message().await?.is_some(), "the echo ended its stream");
        Ok((tx, responses))
    }

    pub async fn stop(self) {
        let _ = self.stop.send(());
        let _ = self.task.await;
    }
}

/// One round trip on an echo stream ([`EchoServer::stream`]): state `i + 1` out, its echo in.
pub(super) async fn echo_once(
    tx: &tokio::sync::mpsc::Sender<pb::ToolState>,
    responses: &mut tonic::Streaming<pb::ToolResponse>,
    i: u64,
) -> anyhow::Result<()> {
    tx.send(bench_tool(i + 1)).await?;
    let r = responses.message().await?.context("the echo ended its stream")?;
    anyhow::ensure!(r.seq == i + 1, "echo {} for tool state {}", r.seq, i + 1);
    Ok(())
}

/// The round trip against [`Echo`] on a free loopback port, paced as the session's.
async fn echo_round_trip(secs: f64) -> anyhow::Result<Percentiles> {
    let echo = EchoServer::start().await?;
    let (tx, mut responses) = echo.stream().await?;
    let rtt = paced(secs, async |i| echo_once(&tx, &mut responses, i).await).await;
    drop(tx);
    echo.stop().await;
    rtt
}
