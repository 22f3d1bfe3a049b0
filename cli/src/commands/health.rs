//! `vademecum health`: one grpc.health.v1 `Check` against a running server, for a container's
//! HEALTHCHECK (the runtime image has no shell and no other probe) or an orchestrator.

use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, bail};
use tonic_health::pb::health_check_response::ServingStatus;
use tonic_health::pb::{HealthCheckRequest, health_client::HealthClient};

use crate::cli::HealthArgs;

/// Asks the server; prints what it said. Exit 0 serving, 1 not serving (or the service is
/// unknown), 2 (an error) when nothing answered within the deadline.
pub fn run(a: HealthArgs) -> anyhow::Result<ExitCode> {
    if !(a.timeout > 0.0 && a.timeout.is_finite()) {
        bail!("--timeout must be a positive number of seconds, got {}", a.timeout);
    }
    let deadline = Duration::from_secs_f64(a.timeout);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the runtime")?;
    let status = runtime.block_on(async {
        tokio::time::timeout(deadline, check(&a))
            .await
            .unwrap_or_else(|_| bail!("no answer from {} within {} s", a.addr, a.timeout))
    })?;
    let service = if a.service.is_empty() { "the server" } else { a.service.as_str() };
    match status {
        Some(ServingStatus::Serving) => {
            println!("{service} at {} is serving", a.addr);
            Ok(ExitCode::SUCCESS)
        }
        other => {
            let said = other.map_or("a status this version does not know".to_string(), |s| s.as_str_name().to_string());
            println!("{service} at {} is not serving: {said}", a.addr);
            Ok(ExitCode::FAILURE)
        }
    }
}

/// One `Check`: the status the server gave, `Ok(Some(ServiceUnknown))` for a service it does
/// not know (`NOT_FOUND`), an error when it could not be asked.
async fn check(a: &HealthArgs) -> anyhow::Result<Option<ServingStatus>> {
    let channel = connect(&a.addr, a.ca.as_deref()).await?;
    let answer = HealthClient::new(channel)
        .check(HealthCheckRequest {
            service: a.service.clone(),
        })
        .await;
    match answer {
        Ok(r) => Ok(ServingStatus::try_from(r.into_inner().status).ok()),
        Err(s) if s.code() == tonic::Code::NotFound => Ok(Some(ServingStatus::ServiceUnknown)),
        Err(s) => Err(anyhow::Error::new(s).context(format!("{} did not answer the health check", a.addr))),
    }
}

/// A channel to `addr` (`http://` or `https://`, trusting `ca` when given).
pub(super) async fn connect(addr: &str, ca: Option<&std::path::Path>) -> anyhow::Result<tonic::transport::Channel> {
    let mut endpoint = tonic::transport::Channel::from_shared(addr.to_string())
        .with_context(|| format!("--addr {addr} is not a URL like http://127.0.0.1:50051"))?;
    if addr.starts_with("https://") {
        let mut tls = tonic::transport::ClientTlsConfig::new();
        if let Some(ca) = ca {
            let pem = super::credential(ca).with_context(|| format!("cannot read CA certificate {}", ca.display()))?;
            tls = tls.ca_certificate(tonic::transport::Certificate::from_pem(pem));
        }
        endpoint = endpoint.tls_config(tls).context("cannot set up TLS")?;
    }
    endpoint.connect().await.with_context(|| format!("cannot connect to {addr}"))
}
