//! Agones integration (`vademecum serve --agones`): the server as a `GameServer` of an Agones
//! `Fleet` (`deploy/k8s/`), through the Agones SDK sidecar's gRPC contract
//! ([`vademecum_proto::agones`], generated from Agones' own protos with the project's tonic).
//!
//! - **Ready** once serving: the GameServer joins the fleet's pool of allocatable servers.
//! - **Health** pings every [`HEALTH_EVERY`]: Agones restarts a GameServer that stops pinging.
//! - The Counter **`sessions`** (capacity `--max-sessions`) follows the sessions held, so that a
//!   `GameServerAllocation` can select servers with room (`minAvailableCapacity`) and pack them.
//! - **Allocate** when the first session starts: an Allocated GameServer is never removed by a
//!   fleet scale-down or a rolling update, so live sessions are protected; **Ready** again when
//!   the last one closes (unless draining), so an idle server can be scaled away.
//! - **Shutdown** when a draining server holds no session any more (`vademecum drain`, the
//!   pod's preStop hook): Agones deletes it and the fleet replaces it.

use std::time::Duration;

use tokio::sync::{mpsc, watch};
use tonic::transport::Channel;
use vademecum_proto::agones::{beta, sdk};

use crate::registry::Occupancy;

/// How often the server tells Agones it is healthy (the Fleet's `health.periodSeconds` is 5).
pub const HEALTH_EVERY: Duration = Duration::from_secs(2);

/// The Counter the server keeps at its session count.
pub const SESSIONS_COUNTER: &str = "sessions";

/// How long [`Sdk::connect`] waits for the sidecar to answer.
pub const CONNECT_WITHIN: Duration = Duration::from_secs(30);

/// A client of the Agones SDK sidecar: the stable service (state changes, health) and the beta
/// one (Counters), on one channel.
#[derive(Clone)]
pub struct Sdk {
    stable: sdk::sdk_client::SdkClient<Channel>,
    beta: beta::sdk_client::SdkClient<Channel>,
}

impl Sdk {
    /// Connects to the sidecar on `localhost:AGONES_SDK_GRPC_PORT` (9357 when unset, as every
    /// Agones SDK does), asking for the GameServer every 100 ms until it answers, for at most
    /// [`CONNECT_WITHIN`] (the sidecar may start after the game server's container).
    pub async fn connect() -> anyhow::Result<Self> {
        let port = std::env::var("AGONES_SDK_GRPC_PORT").unwrap_or_else(|_| "9357".into());
        let port: u16 = port
            .parse()
            .map_err(|_| anyhow::anyhow!("--agones: AGONES_SDK_GRPC_PORT={port:?} is not a port number"))?;
        let channel = Channel::from_shared(format!("http://localhost:{port}"))?
            .connect_timeout(CONNECT_WITHIN)
            .connect_lazy();
        let mut stable = sdk::sdk_client::SdkClient::new(channel.clone());
        let answered = tokio::time::timeout(CONNECT_WITHIN, async {
            let mut tries = tokio::time::interval(Duration::from_millis(100));
            loop {
                tries.tick().await;
                match stable.get_game_server(sdk::Empty {}).await {
                    Ok(_) => return,
                    Err(e) => tracing::debug!(error = %e, "Agones: the SDK sidecar does not answer yet"),
                }
            }
        })
        .await;
        answered.map_err(|_| {
            anyhow::anyhow!(
                "--agones: no Agones SDK server answered on localhost:{port} within {} s: run under an Agones Fleet, or drop --agones",
                CONNECT_WITHIN.as_secs()
            )
        })?;
        Ok(Self {
            stable,
            beta: beta::sdk_client::SdkClient::new(channel),
        })
    }

    /// Marks the GameServer Ready (allocatable).
    pub async fn ready(&mut self) -> Result<(), tonic::Status> {
        self.stable.ready(sdk::Empty {}).await.map(drop)
    }

    /// Allocates the GameServer to itself (protected from scale-down).
    pub async fn allocate(&mut self) -> Result<(), tonic::Status> {
        self.stable.allocate(sdk::Empty {}).await.map(drop)
    }

    /// Asks Agones to shut the GameServer down.
    pub async fn shutdown(&mut self) -> Result<(), tonic::Status> {
        self.stable.shutdown(sdk::Empty {}).await.map(drop)
    }

    /// Pings the Health stream every `every`, on a task of its own (so a slow state change
    /// never delays a ping), reopening the stream a second after the sidecar ends it. The
    /// task runs until the returned handle is aborted.
    pub fn keep_healthy(&self, every: Duration) -> tokio::task::JoinHandle<()> {
        let client = self.stable.clone();
        tokio::spawn(async move {
            loop {
                let (ping, pings) = mpsc::channel(1);
                let call = tokio::spawn({
                    let mut client = client.clone();
                    async move { client.health(tokio_stream::wrappers::ReceiverStream::new(pings)).await }
                });
                let mut ticks = tokio::time::interval(every);
                // a send fails once the call has ended (its stream dropped)
                while ping.send(sdk::Empty {}).await.is_ok() {
                    ticks.tick().await;
                }
                if let Ok(Err(e)) = call.await {
                    tracing::warn!(error = %e, "Agones: the Health stream ended");
                }
                tokio::time::sleep(Duration::from_secs(1)).await;
            }
        })
    }

    /// Sets a Counter's count or capacity (beta Counters; the Counter must be declared in the
    /// GameServer's spec).
    async fn update_counter(&mut self, name: &str, count: Option<i64>, capacity: Option<i64>) -> Result<(), tonic::Status> {
        let update = beta::CounterUpdateRequest {
            name: name.to_owned(),
            count,
            capacity,
            count_diff: 0,
        };
        self.beta
            .update_counter(beta::UpdateCounterRequest {
                counter_update_request: Some(update),
            })
            .await
            .map(drop)
    }
}

/// What the GameServer should be told after a change of occupancy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transition {
    /// Nothing but the counter.
    None,
    /// The first session: Allocate (protected from scale-down).
    Allocate,
    /// The last session closed: Ready (back to the pool).
    Ready,
    /// Drained: Shutdown.
    Shutdown,
}

/// The transition from `allocated` (the GameServer's state as this server last set it) at
/// occupancy `now`.
pub fn transition(allocated: bool, now: Occupancy) -> Transition {
    match (allocated, now.sessions, now.draining) {
        (_, 0, true) => Transition::Shutdown,
        (false, n, _) if n > 0 => Transition::Allocate,
        (true, 0, false) => Transition::Ready,
        _ => Transition::None,
    }
}

/// Runs the GameServer's side for as long as the server runs: Ready, health pings, the
/// sessions Counter, Allocate / Ready / Shutdown as sessions come and go. SDK errors are
/// logged, never fatal: the sessions keep running.
pub async fn follow(mut sdk: Sdk, mut occupancy: watch::Receiver<Occupancy>, capacity: u32) {
    if let Err(e) = sdk.update_counter(SESSIONS_COUNTER, None, Some(i64::from(capacity))).await {
        tracing::warn!(error = %e, "Agones: cannot set the sessions Counter's capacity (declare counters.sessions in the GameServer spec)");
    }
    match sdk.ready().await {
        Ok(()) => tracing::info!("Agones: Ready"),
        Err(e) => tracing::error!(error = %e, "Agones: Ready refused"),
    }
    let health = sdk.keep_healthy(HEALTH_EVERY);
    let (mut allocated, mut shut) = (false, false);
    // until the server stops
    while occupancy.changed().await.is_ok() {
        let now = *occupancy.borrow_and_update();
        if let Err(e) = sdk.update_counter(SESSIONS_COUNTER, Some(i64::from(now.sessions)), None).await {
            tracing::warn!(error = %e, sessions = now.sessions, "Agones: cannot update the sessions Counter");
        }
        let step = transition(allocated, now);
        let done = match step {
            Transition::None => Ok(()),
            Transition::Allocate => sdk.allocate().await.map(|()| allocated = true),
            Transition::Ready => sdk.ready().await.map(|()| allocated = false),
            Transition::Shutdown if !shut => sdk.shutdown().await.map(|()| shut = true),
            Transition::Shutdown => Ok(()),
        };
        match done {
            Ok(()) if step != Transition::None => tracing::info!(?step, sessions = now.sessions, "Agones: state set"),
            Ok(()) => {}
            Err(e) => tracing::error!(?step, error = %e, "Agones refused a state change"),
        }
    }
    health.abort();
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(sessions: u32, draining: bool) -> Occupancy {
        Occupancy { sessions, draining }
    }

    #[test]
    fn a_game_server_is_allocated_while_it_holds_sessions_and_shut_down_once_drained() {
        assert_eq!(transition(false, at(1, false)), Transition::Allocate);
        assert_eq!(transition(true, at(2, false)), Transition::None);
        assert_eq!(transition(true, at(0, false)), Transition::Ready);
        assert_eq!(transition(false, at(0, false)), Transition::None);
        // draining: stays allocated while sessions run, shuts down when none is left
        assert_eq!(transition(true, at(1, true)), Transition::None);
        assert_eq!(transition(true, at(0, true)), Transition::Shutdown);
        assert_eq!(transition(false, at(0, true)), Transition::Shutdown);
    }
}
