//! Agones integration (`vademecum serve --agones`, cargo feature `agones`): the server as a
//! `GameServer` of an Agones `Fleet` (`deploy/k8s/`), through the Agones SDK sidecar.
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

use tokio::sync::watch;

use crate::registry::Occupancy;

/// How often the server tells Agones it is healthy (the Fleet's `health.periodSeconds` is 5).
pub const HEALTH_EVERY: Duration = Duration::from_secs(2);

/// The Counter the server keeps at its session count.
pub const SESSIONS_COUNTER: &str = "sessions";

/// Connects to the Agones SDK sidecar (`AGONES_SDK_GRPC_PORT`, 9357 by default), waiting up to
/// 30 s for it.
pub async fn connect() -> anyhow::Result<agones::Sdk> {
    agones::Sdk::new(None, Some(Duration::from_secs(30))).await.map_err(|e| {
        anyhow::anyhow!(
            "--agones: no Agones SDK server answered on localhost:{} within 30 s ({e}): run under an Agones Fleet, or drop --agones",
            std::env::var("AGONES_SDK_GRPC_PORT").unwrap_or_else(|_| "9357".into())
        )
    })
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
pub async fn follow(mut sdk: agones::Sdk, mut occupancy: watch::Receiver<Occupancy>, capacity: u32) {
    let mut beta = sdk.beta().clone();
    if let Err(e) = beta.set_counter_capacity(SESSIONS_COUNTER, i64::from(capacity)).await {
        tracing::warn!(error = %e, "Agones: cannot set the sessions Counter's capacity (declare counters.sessions in the GameServer spec)");
    }
    match sdk.ready().await {
        Ok(()) => tracing::info!("Agones: Ready"),
        Err(e) => tracing::error!(error = %e, "Agones: Ready refused"),
    }
    let health = sdk.health_check();
    let mut pings = tokio::time::interval(HEALTH_EVERY);
    let (mut allocated, mut shut) = (false, false);
    loop {
        tokio::select! {
            _ = pings.tick() => {
                let _ = health.try_send(());
            }
            changed = occupancy.changed() => {
                if changed.is_err() {
                    return; // the server stopped
                }
                let now = *occupancy.borrow_and_update();
                if let Err(e) = beta.set_counter_count(SESSIONS_COUNTER, i64::from(now.sessions)).await {
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
        }
    }
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
