//! The vademecum server: sessions that simulate a scene in real time, and the gRPC services
//! in front of them.
//!
//! # Layout
//! - [`session`]: a session — a scene, its loaded bundles shared read-only, the effect
//!   pipeline — and its threads: the real-time tick thread (1 kHz, owns the pipeline, never
//!   awaits, never takes a lock a request handler can hold) and the frame thread (displacement
//!   frames for viewers at display rate, through a latest-value slot). Scripted trajectories
//!   for headless runs, and tick statistics.
//! - [`registry`]: live sessions by id with their owners; the cache of loaded bundles.
//!   [`bundle_fetch`]: bundles pinned by digest fetched from a bundle source into the store.
//! - [`service`]: the gRPC services (`Info`, `Sessions`, `Interaction`, `Viewing`), one thin
//!   file each; [`convert`] holds every wire ↔ engine conversion, [`error`] the one mapping
//!   of errors to status codes, [`auth`] the bearer-token interceptor.
//! - [`fleet`]: a fleet of servers routing sessions between them (placement by load reports,
//!   redirects, draining).
//! - `agones`: the server as an Agones GameServer (`--agones`).
//! - [`web`]: the browser viewer and gRPC-web (`--web`).
//! - [`metrics`]: the Prometheus endpoint. [`config`]: the settings.
//!
//! # Shutdown
//! [`run`] stops when its `shutdown` future resolves: the server stops accepting
//! connections, every session is closed (its tick thread finishes the current tick; open
//! streams end with OK), in-flight calls complete, and the sessions' threads are joined as
//! the last stream lets go of each.
//!
//! The `vademecum` command line that starts it (`serve`) and drives it headless (`run`) is the
//! `vademecum-cli` crate, above this one; this library depends on neither the client SDK nor
//! the plotting and progress crates.

pub mod agones;
pub mod auth;
pub mod bundle_fetch;
pub mod config;
pub mod convert;
pub mod error;
pub mod fleet;
pub mod metrics;
pub mod registry;
pub mod service;
pub mod session;
pub mod web;

use std::future::Future;

use anyhow::Context;

use tonic::service::interceptor::InterceptedService;
use vademecum_proto::v1 as pb;

use crate::auth::Auth;
use crate::config::ServerConfig;
use crate::registry::Registry;
use crate::service::{
    fleet::FleetService, info::InfoService, interaction::InteractionService, sessions::SessionsService, viewing::ViewingService,
};

/// Serves the gRPC API on `listener` (and Prometheus metrics on `metrics`, the browser viewer
/// and gRPC-web on `web`, if given) until `shutdown` resolves.
pub async fn run(
    listener: tokio::net::TcpListener,
    metrics: Option<tokio::net::TcpListener>,
    web: Option<tokio::net::TcpListener>,
    config: ServerConfig,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> anyhow::Result<()> {
    let mut config = config;
    if config.session.ticking.is_none() && config.tick_workers.workers > 0 {
        let workers = session::TickScheduler::new(config.tick_workers).context("cannot start the tick workers")?;
        tracing::info!(workers = config.tick_workers.workers, realtime = ?workers.realtime(), "tick workers started");
        config.session.ticking = Some(std::sync::Arc::new(workers));
        if config.session.answering.is_none() {
            // as many answer workers as tick workers: each wakes on its sessions' answers
            let answering = session::AnswerWorkers::new(config.tick_workers.workers).context("cannot start the answer workers")?;
            config.session.answering = Some(std::sync::Arc::new(answering));
        }
    }
    if config.session.devices.is_none() && config.device_workers > 0 {
        let workers = session::DeviceWorkers::new(session::DeviceWorkersConfig {
            workers: config.device_workers,
            fifo_priority: Some(session::DEVICE_FIFO_PRIORITY),
            on_start: None,
        })
        .context("cannot start the device workers")?;
        tracing::info!(workers = config.device_workers, realtime = ?workers.realtime(), "device workers started");
        config.session.devices = Some(std::sync::Arc::new(workers));
    }
    if config.session.framing.is_none() && config.frame_workers.workers > 0 {
        let workers = session::FrameWorkers::new(config.frame_workers).context("cannot start the frame workers")?;
        tracing::info!(workers = config.frame_workers.workers, "frame workers started");
        config.session.framing = Some(std::sync::Arc::new(workers));
    }
    let registry = Registry::new(config.clone());
    if config.agones {
        let sdk = agones::Sdk::connect().await?;
        let capacity = u32::try_from(config.max_sessions).unwrap_or(u32::MAX);
        tokio::spawn(agones::follow(sdk, registry.occupancy(), capacity));
    }
    let auth = Auth::new(config.tokens.clone());
    let (health, health_service) = tonic_health::server::health_reporter();
    health.set_serving::<pb::sessions_server::SessionsServer<SessionsService>>().await;
    health
        .set_serving::<pb::interaction_server::InteractionServer<InteractionService>>()
        .await;
    health.set_serving::<pb::viewing_server::ViewingServer<ViewingService>>().await;
    health.set_serving::<pb::info_server::InfoServer<InfoService>>().await;
    health.set_serving::<pb::fleet_server::FleetServer<FleetService>>().await;
    let reflection = tonic_reflection::server::Builder::configure()
        .register_encoded_file_descriptor_set(vademecum_proto::FILE_DESCRIPTOR_SET)
        .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
        .build_v1()?;
    let (req, resp) = (config.max_request_bytes, config.max_response_bytes);
    let peers = config.fleet.as_ref().map(fleet::Peers::new).transpose()?;
    let sessions = pb::sessions_server::SessionsServer::new(SessionsService {
        registry: registry.clone(),
        peers,
    })
    .max_decoding_message_size(req)
    .max_encoding_message_size(resp);
    let interaction = pb::interaction_server::InteractionServer::new(InteractionService {
        registry: registry.clone(),
    })
    .max_decoding_message_size(req)
    .max_encoding_message_size(resp);
    let viewing = pb::viewing_server::ViewingServer::new(ViewingService {
        registry: registry.clone(),
    })
    .max_decoding_message_size(req)
    .max_encoding_message_size(resp);
    let info = pb::info_server::InfoServer::new(InfoService);
    let fleet = pb::fleet_server::FleetServer::new(FleetService {
        registry: registry.clone(),
    });
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    let web_task = web.map(|l| {
        let mut rx = stop_rx.clone();
        let services = web::WebServices {
            sessions: sessions.clone(),
            viewing: viewing.clone(),
            info: info.clone(),
        };
        let origins = web::Origins::of(config.tokens.is_some(), &config.web_origins);
        if origins == web::Origins::Only(Vec::new()) {
            tracing::warn!(
                "the web port answers its own page only: without tokens no other origin may call it (give tokens, or name trusted origins with --web-origin)"
            );
        }
        tokio::spawn(web::serve(l, services, auth.clone(), origins, config.tls.clone(), async move {
            let _ = rx.wait_for(|&s| s).await;
        }))
    });
    let metrics_task = metrics.map(|l| {
        let mut rx = stop_rx.clone();
        tokio::spawn(metrics::serve(l, registry.clone(), async move {
            let _ = rx.wait_for(|&s| s).await;
        }))
    });
    let on_shutdown = {
        let registry = registry.clone();
        async move {
            shutdown.await;
            tracing::info!("shutting down: closing every session");
            registry.close_all();
            let _ = stop_tx.send(true);
        }
    };
    let mut builder = tonic::transport::Server::builder();
    if let Some((cert, key)) = &config.tls {
        builder = builder.tls_config(tonic::transport::ServerTlsConfig::new().identity(tonic::transport::Identity::from_pem(cert, key)))?;
    }
    builder
        .add_service(health_service)
        .add_service(reflection)
        .add_service(InterceptedService::new(info, auth.clone()))
        .add_service(InterceptedService::new(fleet, auth.clone()))
        .add_service(InterceptedService::new(sessions, auth.clone()))
        .add_service(InterceptedService::new(interaction, auth.clone()))
        .add_service(InterceptedService::new(viewing, auth))
        .serve_with_incoming_shutdown(incoming(listener), on_shutdown)
        .await?;
    if let Some(t) = metrics_task {
        let _ = t.await;
    }
    if let Some(t) = web_task {
        match t.await {
            Ok(Err(e)) => tracing::error!(error = %e, "the web viewer's server failed"),
            Err(e) => tracing::error!(error = %e, "the web viewer's server panicked"),
            Ok(Ok(())) => {}
        }
    }
    Ok(())
}

/// The connections accepted on `listener`, with `TCP_NODELAY` set: a tool state's answer is a
/// small write that Nagle's algorithm would hold until the client's delayed ACK (up to 40 ms).
/// (tonic applies its own `tcp_nodelay` only to listeners it binds itself.)
pub fn incoming(listener: tokio::net::TcpListener) -> tonic::transport::server::TcpIncoming {
    tonic::transport::server::TcpIncoming::from(listener).with_nodelay(Some(true))
}
