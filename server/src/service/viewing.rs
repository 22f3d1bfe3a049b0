//! `vademecum.v1.Viewing`: the reference geometry, then one message per period of the
//! viewer's own rate — the latest frame when there is a new one, else a heartbeat — numbered
//! per stream. A viewer that cannot keep up skips frames (bounded channel, `try_send`); the
//! session never waits for it.

use std::pin::Pin;
use std::time::Duration;

use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TrySendError;
use tokio_stream::Stream;
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status};
use vademecum_proto::v1 as pb;

use crate::auth::caller;
use crate::convert;
use crate::registry::{Registry, StreamGuard, StreamKind};

/// Frame rate when the request leaves it at 0 (Hz).
pub const DEFAULT_RATE_HZ: f64 = 30.0;

/// The Viewing service.
#[derive(Debug, Clone)]
pub struct ViewingService {
    /// The sessions.
    pub registry: Registry,
}

type FrameStream = Pin<Box<dyn Stream<Item = Result<pb::Frame, Status>> + Send>>;

#[tonic::async_trait]
impl pb::viewing_server::Viewing for ViewingService {
    type WatchStream = FrameStream;

    async fn watch(&self, req: Request<pb::WatchRequest>) -> Result<Response<Self::WatchStream>, Status> {
        let owner = caller(&req)?;
        let r = req.into_inner();
        if !r.rate_hz.is_finite() || r.rate_hz < 0.0 {
            return Err(Status::invalid_argument(format!(
                "rate_hz must be a non-negative number, got {}",
                r.rate_hz
            )));
        }
        let cap = self.registry.config().max_frame_rate_hz;
        let rate = if r.rate_hz == 0.0 { DEFAULT_RATE_HZ } else { r.rate_hz.min(cap) };
        let entry = self.registry.get(&owner, &r.session_id)?;
        let permit = self.registry.open_stream(&owner, StreamKind::Watch)?;
        let (tx, rx) = mpsc::channel(2);
        tokio::spawn(async move {
            let _permit = permit;
            let _guard = StreamGuard::new(&entry.viewers);
            let mut frames = entry.session.subscribe_frames();
            let mut closed = entry.closed.subscribe();
            if tx.send(Ok(convert::geometry_frame(entry.session.geometry()))).await.is_err() {
                return;
            }
            let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / rate));
            every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            // the session frame last sent, and this stream's own count of frames
            let (mut last, mut sent) = (0u64, 0u64);
            let period_s = entry.session.config().period.as_secs_f64();
            loop {
                tokio::select! {
                    _ = every.tick() => {
                        let f = frames.borrow_and_update().clone();
                        let msg = if f.seq > last {
                            last = f.seq;
                            sent += 1;
                            convert::frame(&f, sent)
                        } else {
                            let tick = entry.session.stats().ticks.load(std::sync::atomic::Ordering::Relaxed);
                            convert::heartbeat(&f, sent, tick, tick as f64 * period_s)
                        };
                        match tx.try_send(Ok(msg)) {
                            Ok(()) | Err(TrySendError::Full(_)) => {}
                            Err(TrySendError::Closed(_)) => return,
                        }
                    }
                    _ = closed.changed() => return,
                    _ = tx.closed() => return,
                }
            }
        });
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }
}
