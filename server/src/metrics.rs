//! A Prometheus text-format endpoint (`GET /metrics`): sessions, connected clients, and per
//! session the tick-work and response-latency histograms, deadline misses and counters.

use std::fmt::Write;
use std::sync::atomic::Ordering;

use hdrhistogram::Histogram;

use crate::registry::{Entry, Registry};

/// Histogram bucket bounds (s).
const BUCKETS_S: [f64; 12] = [5e-6, 1e-5, 2.5e-5, 5e-5, 1e-4, 2.5e-4, 5e-4, 1e-3, 2.5e-3, 5e-3, 1e-2, 1e-1];

fn histogram(out: &mut String, name: &str, session: &str, h: &Histogram<u64>) {
    for le in BUCKETS_S {
        let n = h.count_between(0, (le * 1e9) as u64);
        let _ = writeln!(out, "{name}_bucket{{{session},le=\"{le}\"}} {n}");
    }
    let _ = writeln!(out, "{name}_bucket{{{session},le=\"+Inf\"}} {}", h.len());
    let _ = writeln!(out, "{name}_sum{{{session}}} {}", h.mean() * h.len() as f64 * 1e-9);
    let _ = writeln!(out, "{name}_count{{{session}}} {}", h.len());
}

/// The label set naming a session's series: `session="s7"` (the session's ordinal, which
/// grants nothing: the id's unguessable part is never shown) and `label="…"` (the label its
/// creator gave, escaped). The page is unauthenticated, so it shows nothing secret.
fn series(e: &Entry) -> String {
    let ordinal = e.session.id().split('-').next().unwrap_or("");
    format!("session=\"{ordinal}\",label=\"{}\"", escape(&e.label))
}

/// A label value as the exposition format writes it: `\`, `"` and newlines escaped.
fn escape(value: &str) -> String {
    value
        .chars()
        .flat_map(|c| match c {
            '\\' => vec!['\\', '\\'],
            '"' => vec!['\\', '"'],
            '\n' => vec!['\\', 'n'],
            c => vec![c],
        })
        .collect()
}

/// The exposition text for every session.
pub fn render(registry: &Registry) -> String {
    let all = registry.all();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# HELP vademecum_sessions Sessions running.\n# TYPE vademecum_sessions gauge\nvademecum_sessions {}",
        all.len()
    );
    let gauges = [
        ("vademecum_interacting_clients", "Interaction streams open.", "gauge"),
        ("vademecum_viewers", "Viewer streams open.", "gauge"),
        ("vademecum_ticks_total", "Ticks run.", "counter"),
        (
            "vademecum_deadline_misses_total",
            "Ticks started more than one period late.",
            "counter",
        ),
        ("vademecum_answers_total", "Tool states answered.", "counter"),
        (
            "vademecum_rejected_inputs_total",
            "Tool states rejected (non-finite or out of range).",
            "counter",
        ),
        (
            "vademecum_dropped_answers_total",
            "Answers dropped because a reader fell behind.",
            "counter",
        ),
        ("vademecum_frames_total", "Frames produced for viewers.", "counter"),
        (
            "vademecum_fidelity_fallbacks_total",
            "Times the session fell back to its reduced fidelity (ticks close to their deadline).",
            "counter",
        ),
        (
            "vademecum_fidelity_reduced",
            "1 while the session runs at its reduced fidelity.",
            "gauge",
        ),
    ];
    for (i, (name, help, kind)) in gauges.iter().enumerate() {
        let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} {kind}");
        for e in &all {
            let s = e.session.stats();
            let v = match i {
                0 => e.interacting.load(Ordering::Relaxed) as u64,
                1 => e.viewers.load(Ordering::Relaxed) as u64,
                2 => s.ticks.load(Ordering::Relaxed),
                3 => s.misses.load(Ordering::Relaxed),
                4 => s.answered.load(Ordering::Relaxed),
                5 => s.rejected.load(Ordering::Relaxed),
                6 => s.dropped.load(Ordering::Relaxed),
                7 => s.frames.load(Ordering::Relaxed),
                8 => s.fallbacks.load(Ordering::Relaxed),
                _ => u64::from(s.reduced.load(Ordering::Relaxed)),
            };
            let _ = writeln!(out, "{name}{{{}}} {v}", series(e));
        }
    }
    bridge_metrics(&mut out, &all);
    let _ = writeln!(
        out,
        "# HELP vademecum_session_memory_bytes Memory a session holds of its own, by part (shared bundles not counted).\n# TYPE vademecum_session_memory_bytes gauge"
    );
    for e in &all {
        for (part, bytes) in e.session.memory().parts {
            let _ = writeln!(out, "vademecum_session_memory_bytes{{{},part=\"{part}\"}} {bytes}", series(e));
        }
    }
    let config = &registry.config().session;
    if let Some(w) = &config.ticking {
        worker_metrics(&mut out, "tick", &w.utilisation(), &w.load());
    }
    if let Some(w) = &config.framing {
        worker_metrics(&mut out, "frame", &w.utilisation(), &w.load());
    }
    let _ = writeln!(
        out,
        "# HELP vademecum_tick_work_seconds Work per tick.\n# TYPE vademecum_tick_work_seconds histogram"
    );
    let hs: Vec<_> = all.iter().map(|e| (series(e), e.session.stats().histograms())).collect();
    for (id, h) in &hs {
        histogram(&mut out, "vademecum_tick_work_seconds", id, &h.work);
    }
    let _ = writeln!(
        out,
        "# HELP vademecum_response_seconds Tool state in to answer out, inside the server.\n# TYPE vademecum_response_seconds histogram"
    );
    for (id, h) in &hs {
        histogram(&mut out, "vademecum_response_seconds", id, &h.response);
    }
    out
}

/// Each `kind` worker's utilisation and sessions (`vademecum_{kind}_worker_utilisation`,
/// `vademecum_{kind}_worker_sessions`).
fn worker_metrics(out: &mut String, kind: &str, utilisation: &[f64], sessions: &[usize]) {
    let _ = writeln!(
        out,
        "# HELP vademecum_{kind}_worker_utilisation CPU time over wall time of each {kind} worker (last quarter second).\n# TYPE vademecum_{kind}_worker_utilisation gauge"
    );
    for (k, u) in utilisation.iter().enumerate() {
        let _ = writeln!(out, "vademecum_{kind}_worker_utilisation{{worker=\"{k}\"}} {u}");
    }
    let _ = writeln!(
        out,
        "# HELP vademecum_{kind}_worker_sessions Sessions each {kind} worker serves.\n# TYPE vademecum_{kind}_worker_sessions gauge"
    );
    for (k, n) in sessions.iter().enumerate() {
        let _ = writeln!(out, "vademecum_{kind}_worker_sessions{{worker=\"{k}\"}} {n}");
    }
}

/// Per session with a haptic channel: states answered, and each device bridge's own figures
/// from its latest report (latency quantiles as a summary, counters), labelled with the
/// session and the tool the bridge moves.
fn bridge_metrics(out: &mut String, all: &[std::sync::Arc<crate::registry::Entry>]) {
    let haptic: Vec<_> = all.iter().filter(|e| e.session.config().haptic.is_some()).collect();
    let _ = writeln!(
        out,
        "# HELP vademecum_haptic_answers_total Tool states answered on the haptic channel.\n# TYPE vademecum_haptic_answers_total counter"
    );
    for e in &haptic {
        let n = e.session.stats().haptic_answered.load(Ordering::Relaxed);
        let _ = writeln!(out, "vademecum_haptic_answers_total{{{}}} {n}", series(e));
    }
    // a series per bridge: the session's, and the tool its bridge moves
    let reports: Vec<_> = haptic
        .iter()
        .flat_map(|e| {
            let tools = &e.session.scene().spec.tools;
            e.session.stats().bridges.iter().enumerate().filter_map(move |(tool, b)| {
                let name = tools.get(tool).map_or("", |t| t.name());
                b.snapshot().map(|b| (format!("{},tool=\"{}\"", series(e), escape(name)), b))
            })
        })
        .collect();
    let _ = writeln!(
        out,
        "# HELP vademecum_bridge_latency_seconds Device read to force written, in the device bridge.\n# TYPE vademecum_bridge_latency_seconds summary"
    );
    for (id, b) in &reports {
        for (q, v) in [
            ("0.5", b.latency_us.p50),
            ("0.99", b.latency_us.p99),
            ("0.999", b.latency_us.p999),
            ("1", b.latency_us.max),
        ] {
            let _ = writeln!(out, "vademecum_bridge_latency_seconds{{{id},quantile=\"{q}\"}} {}", v * 1e-6);
        }
        let _ = writeln!(out, "vademecum_bridge_latency_seconds_count{{{id}}} {}", b.fresh_forces);
    }
    let counters: [(&str, &str, fn(&crate::session::BridgeSnapshot) -> u64); 5] = [
        ("vademecum_bridge_ticks_total", "Device bridge ticks.", |b| b.ticks),
        (
            "vademecum_bridge_deadline_misses_total",
            "Device bridge ticks that wrote their force more than a period late.",
            |b| b.deadline_misses,
        ),
        (
            "vademecum_bridge_watchdog_ticks_total",
            "Device bridge ticks whose force the watchdog held or faded.",
            |b| b.watchdog_ticks,
        ),
        (
            "vademecum_bridge_input_rejections_total",
            "Device samples held (non-finite) or clamped (jump, workspace).",
            |b| b.input_rejections(),
        ),
        (
            "vademecum_bridge_force_limits_total",
            "Forces zeroed (non-finite), clamped or slewed by the bridge.",
            |b| b.rejected_forces + b.clamped_forces + b.rate_limited_forces,
        ),
    ];
    for (name, help, get) in counters {
        let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} counter");
        for (id, b) in &reports {
            let _ = writeln!(out, "{name}{{{id}}} {}", get(b));
        }
    }
}

/// Serves `GET /metrics` on `listener` until `shutdown` resolves.
pub async fn serve(
    listener: tokio::net::TcpListener,
    registry: Registry,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let app = axum::Router::new().route(
        "/metrics",
        axum::routing::get(move || {
            let registry = registry.clone();
            async move { ([("content-type", "text/plain; version=0.0.4")], render(&registry)) }
        }),
    );
    axum::serve(listener, app).with_graceful_shutdown(shutdown).await
}
