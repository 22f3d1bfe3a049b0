//! `vademecum drain`: Fleet.Drain on a server of this host, then wait for its sessions to
//! close (a Kubernetes preStop hook; an operator before maintenance).

use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use tonic::metadata::MetadataValue;
use vademecum_proto::v1 as pb;

use crate::cli::DrainArgs;

/// How often the load is asked while waiting.
const POLL: Duration = Duration::from_millis(500);

/// The token to present: `--token`, else the first of `--tokens-file`, else VADEMECUM_TOKEN,
/// else the first of VADEMECUM_TOKENS.
fn token(a: &DrainArgs) -> anyhow::Result<Option<String>> {
    if let Some(t) = &a.token {
        return Ok(Some(t.clone()));
    }
    if let Some(f) = &a.tokens_file {
        return Ok(super::tokens_in_file(f)?.into_iter().next());
    }
    let first = |v: String| super::comma_list(&v).into_iter().next();
    Ok(std::env::var("VADEMECUM_TOKEN")
        .ok()
        .and_then(first)
        .or_else(|| std::env::var("VADEMECUM_TOKENS").ok().and_then(first)))
}

/// Exit 0 when the server holds no session, 1 when `--wait` ran out first, 2 (an error) when
/// it could not be asked.
pub fn run(a: DrainArgs) -> anyhow::Result<ExitCode> {
    if !(a.wait >= 0.0 && a.wait.is_finite()) {
        bail!("--wait must be a number of seconds ≥ 0, got {}", a.wait);
    }
    let bearer = match token(&a)? {
        Some(t) => Some(MetadataValue::try_from(format!("Bearer {t}")).context("the token cannot be sent as metadata")?),
        None => None,
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the runtime")?;
    runtime.block_on(async {
        let channel = super::health::connect(&a.addr, a.ca.as_deref()).await?;
        let mut fleet = pb::fleet_client::FleetClient::with_interceptor(channel, move |mut req: tonic::Request<()>| {
            if let Some(b) = &bearer {
                req.metadata_mut().insert("authorization", b.clone());
            }
            Ok(req)
        });
        let load = fleet
            .drain(pb::DrainRequest { resume: a.resume })
            .await
            .with_context(|| format!("{} refused to drain", a.addr))?
            .into_inner();
        if a.resume {
            println!("{} takes new sessions again ({} running)", a.addr, load.sessions);
            return Ok(ExitCode::SUCCESS);
        }
        println!("{} is draining: no new session; {} running", a.addr, load.sessions);
        let deadline = Instant::now() + Duration::from_secs_f64(a.wait);
        let mut left = load.sessions;
        while left > 0 {
            if Instant::now() >= deadline {
                println!("{left} sessions still running after {} s: they close when the server stops", a.wait);
                return Ok(ExitCode::FAILURE);
            }
            tokio::time::sleep(POLL.min(deadline.saturating_duration_since(Instant::now()))).await;
            let now = fleet
                .get_load(pb::GetLoadRequest {})
                .await
                .with_context(|| format!("{} stopped answering", a.addr))?
                .into_inner()
                .sessions;
            if now != left {
                println!("{now} sessions running");
            }
            left = now;
        }
        println!("{} holds no session", a.addr);
        Ok(ExitCode::SUCCESS)
    })
}
