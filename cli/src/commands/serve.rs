//! `vademecum serve`: the gRPC server.

use std::io::Write;
use std::process::ExitCode;

use anyhow::{Context, bail};
use vademecum_bridge::timing::WaitStrategy;
use vademecum_server::config::ServerConfig;

use crate::cli::ServeArgs;

fn tokens(a: &ServeArgs) -> anyhow::Result<Option<Vec<String>>> {
    let mut tokens: Vec<String> = match &a.tokens_file {
        Some(f) => super::tokens_in_file(f)?,
        None => Vec::new(),
    };
    if let Some(env) = std::env::var_os("VADEMECUM_TOKENS") {
        let listed = super::comma_list(&env.to_string_lossy());
        if listed.is_empty() {
            bail!("VADEMECUM_TOKENS is set but holds no token; unset it and pass --no-auth to serve without authentication");
        }
        tokens.extend(listed);
    }
    match (tokens.is_empty(), a.no_auth) {
        (false, true) => bail!("--no-auth with tokens given (VADEMECUM_TOKENS or --tokens-file): choose one"),
        (false, false) => Ok(Some(tokens)),
        (true, true) => Ok(None),
        (true, false) => {
            bail!("no authentication configured: give --tokens-file FILE or VADEMECUM_TOKENS, or --no-auth to let every client in")
        }
    }
}

/// The server's name: `--name`, else the host name (a pod's name), else "vademecum".
fn name(a: &ServeArgs) -> anyhow::Result<String> {
    if let Some(n) = &a.name {
        if !vademecum_server::fleet::valid_name(n) {
            bail!("--name '{n}' must be 1 to 40 of A-Z a-z 0-9 . _ -");
        }
        return Ok(n.clone());
    }
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    let host = host.trim();
    Ok(if vademecum_server::fleet::valid_name(host) {
        host
    } else {
        "vademecum"
    }
    .to_string())
}

/// The fleet settings: `--peer` and VADEMECUM_PEERS, with `--advertise`.
fn fleet(a: &ServeArgs) -> anyhow::Result<Option<vademecum_server::fleet::FleetConfig>> {
    let mut peers = a.peers.clone();
    if let Ok(env) = std::env::var("VADEMECUM_PEERS") {
        peers.extend(super::comma_list(&env));
    }
    let Some(advertise) = a.advertise.clone() else {
        if !peers.is_empty() {
            bail!("peers given (--peer or VADEMECUM_PEERS) without --advertise: say the address clients reach this server at");
        }
        return Ok(None);
    };
    for p in peers.iter().chain([&advertise]) {
        if !(p.starts_with("http://") || p.starts_with("https://")) {
            bail!("fleet address '{p}' must be a URL like http://host:50051");
        }
    }
    // a server listed among its own peers would place sessions on itself through a hop
    peers.retain(|p| p != &advertise);
    let peer_ca = match &a.peer_ca {
        Some(f) => Some(super::credential(f).with_context(|| format!("cannot read --peer-ca {}", f.display()))?),
        None => None,
    };
    Ok(Some(vademecum_server::fleet::FleetConfig { advertise, peers, peer_ca }))
}

/// Resolves on SIGINT (Ctrl-C) or SIGTERM (systemd, Kubernetes, `docker stop`).
async fn stop_signal() {
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        _ = term => {}
    }
}

/// Refuses counts, rates and worker numbers out of their range before anything starts.
fn check_arguments(a: &ServeArgs) -> anyhow::Result<()> {
    if a.max_sessions == 0
        || a.client_sessions == 0
        || a.max_streams == 0
        || a.client_streams == 0
        || a.max_scene_cells == 0
        || a.max_preparing == 0
    {
        bail!(
            "--max-sessions, --client-sessions, --max-streams, --client-streams, --max-scene-cells and --max-preparing must be at least 1"
        );
    }
    if !(a.max_frame_rate > 0.0 && a.max_frame_rate <= 240.0) {
        bail!("--max-frame-rate must lie in (0, 240] Hz, got {}", a.max_frame_rate);
    }
    if !(a.max_tick_load > 0.0 && a.max_tick_load <= 1.0) {
        bail!("--max-tick-load must lie in (0, 1], got {}", a.max_tick_load);
    }
    for (flag, n) in [
        ("--tick-workers", a.tick_workers),
        ("--frame-workers", a.frame_workers),
        ("--device-workers", Some(a.device_workers)),
    ] {
        if let Some(n) = n.filter(|&n| n > 256) {
            bail!("{flag} {n} is more than 256: one per CPU is the default");
        }
    }
    Ok(())
}

/// What `serve` says on stdout once it listens: where, how (TLS, tokens), as what (Agones,
/// fleet), and whether it holds the CPU's wake-up latency.
fn print_banner(
    a: &ServeArgs,
    wake_latency: &Option<Result<vademecum_bridge::timing::WakeLatencyRequest, vademecum_bridge::timing::Refused>>,
    listener: &tokio::net::TcpListener,
    metrics: Option<&tokio::net::TcpListener>,
    web: Option<&tokio::net::TcpListener>,
    config: &ServerConfig,
) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match wake_latency {
        Some(Ok(_)) => writeln!(out, "CPU wake-up latency: held at {} µs", a.wake_latency_us.unwrap_or(0))?,
        Some(Err(e)) => writeln!(out, "CPU wake-up latency: not held ({e})")?,
        None => {}
    }
    writeln!(out, "listening on {}", listener.local_addr()?)?;
    if let Some(m) = metrics {
        writeln!(out, "metrics on http://{}/metrics", m.local_addr()?)?;
    }
    if let Some(w) = web {
        writeln!(out, "web viewer on http://{}/", w.local_addr()?)?;
    }
    writeln!(
        out,
        "transport: {}",
        if config.tls.is_some() { "TLS (rustls)" } else { "plain HTTP/2" }
    )?;
    writeln!(
        out,
        "authentication: {}",
        if config.tokens.is_some() {
            "bearer tokens"
        } else {
            "none (every client is 'anonymous')"
        }
    )?;
    if config.agones {
        writeln!(out, "agones: a GameServer (Ready once serving; Allocated while it holds sessions)")?;
    }
    if let Some(f) = &config.fleet {
        writeln!(
            out,
            "fleet: {} at {}, with {} peers (sessions are placed on the least-loaded server)",
            config.name,
            f.advertise,
            f.peers.len()
        )?;
    }
    out.flush()?;
    Ok(())
}

pub fn run(a: ServeArgs) -> anyhow::Result<ExitCode> {
    check_arguments(&a)?;
    let tls = match (&a.tls_cert, &a.tls_key) {
        (Some(c), Some(k)) => Some((
            super::credential(c).with_context(|| format!("cannot read TLS certificate {}", c.display()))?,
            super::credential(k).with_context(|| format!("cannot read TLS key {}", k.display()))?,
        )),
        (None, None) => None,
        _ => bail!("--tls-cert and --tls-key go together"),
    };
    let haptic_wait = match (a.device_workers, a.haptic_wait) {
        (0, w) => w,
        (_, None | Some(WaitStrategy::Event)) => Some(WaitStrategy::Event),
        (_, Some(w)) => {
            bail!("--device-workers waits for the bridges' events (--haptic-wait event), not --haptic-wait {w}: drop one of the two")
        }
    };
    let config = ServerConfig {
        tls,
        scene_root: a.scene_root.clone(),
        mesh_root: a.mesh_root.clone().unwrap_or_else(|| a.scene_root.clone()),
        bundle_root: a.bundle_root.clone(),
        allow_paths: !a.no_paths,
        max_sessions: a.max_sessions,
        max_scene_cells: a.max_scene_cells,
        max_preparing: a.max_preparing,
        client_sessions: a.client_sessions,
        max_streams: a.max_streams,
        client_streams: a.client_streams,
        max_frame_rate_hz: a.max_frame_rate,
        tokens: tokens(&a)?,
        web_origins: a
            .web_origin
            .iter()
            .map(|o| {
                let ok = (o.starts_with("http://") || o.starts_with("https://"))
                    && o.parse::<axum::http::HeaderValue>().is_ok()
                    && !o.trim_end_matches('/').contains(['*', ' ']);
                if ok {
                    Ok(o.trim_end_matches('/').to_string())
                } else {
                    Err(anyhow::anyhow!(
                        "--web-origin '{o}' must be an origin: http(s)://host[:port], no wildcard"
                    ))
                }
            })
            .collect::<anyhow::Result<_>>()?,
        tick_workers: vademecum_server::session::SchedulerConfig {
            workers: a
                .tick_workers
                .unwrap_or(vademecum_server::session::SchedulerConfig::default().workers),
            pin: a.pin_tick_workers,
            fifo_priority: a.tick_fifo,
            on_start: None,
            max_utilisation: a.max_tick_load,
        },
        haptic_wait,
        device_workers: a.device_workers,
        frame_workers: vademecum_server::session::FrameWorkersConfig {
            workers: a
                .frame_workers
                .unwrap_or(vademecum_server::session::FrameWorkersConfig::default().workers),
        },
        session: vademecum_server::session::SessionConfig {
            fallback: !a.no_fidelity_fallback,
            ..ServerConfig::default().session
        },
        name: name(&a)?,
        fleet: fleet(&a)?,
        agones: a.agones,
        bundle_store: a.bundle_store.clone(),
        bundle_source: match &a.bundle_source {
            Some(u) if !(u.starts_with("http://") || u.starts_with("https://")) => {
                bail!("--bundle-source '{u}' must be an http:// or https:// URL")
            }
            other => other.clone(),
        },
        bundle_fetch: vademecum_server::bundle_fetch::FetchLimits {
            deadline: match a.bundle_fetch_timeout {
                s if s.is_finite() && s > 0.0 && s <= 86_400.0 => std::time::Duration::from_secs_f64(s),
                s => bail!("--bundle-fetch-timeout must lie in (0, 86400] seconds, got {s}"),
            },
            max_bytes: match a.bundle_fetch_max_mib {
                m @ 1..=1_048_576 => m << 20,
                m => bail!("--bundle-fetch-max-mib must lie in [1, 1048576] MiB, got {m}"),
            },
        },
        ..ServerConfig::default()
    };
    // held while the server runs (released when dropped)
    let wake_latency = a.wake_latency_us.map(vademecum_bridge::timing::request_wake_latency);
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::bind(&a.listen)
            .await
            .with_context(|| format!("cannot listen on {}", a.listen))?;
        let metrics = match &a.metrics {
            Some(addr) => {
                let l = tokio::net::TcpListener::bind(addr)
                    .await
                    .with_context(|| format!("cannot listen on {addr} for metrics"))?;
                if !l.local_addr()?.ip().is_loopback() && !a.metrics_public {
                    bail!("--metrics {addr} is not a loopback address: the metrics page is unauthenticated; add --metrics-public to serve it there");
                }
                Some(l)
            }
            None => None,
        };
        let web = match &a.web {
            Some(addr) => Some(
                tokio::net::TcpListener::bind(addr)
                    .await
                    .with_context(|| format!("cannot listen on {addr} for the web viewer"))?,
            ),
            None => None,
        };
        print_banner(&a, &wake_latency, &listener, metrics.as_ref(), web.as_ref(), &config)?;
        vademecum_server::run(listener, metrics, web, config, stop_signal()).await
    })?;
    Ok(ExitCode::SUCCESS)
}
