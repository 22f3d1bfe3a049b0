//! `vademecum.v1.Viewing`: the reference geometry, then one message per period of the
//! viewer's own rate — the latest frame when there is a new one, else a heartbeat — numbered
//! per stream. The session never waits for a viewer.
//!
//! Two ways to keep a slow viewer from seeing old frames:
//! - `Watch` skips a period when the stream's two-message channel to the transport is full
//!   (the transport stops taking messages when HTTP/2 flow control closes). What the
//!   client's own stack has already accepted is beyond the server's reach.
//! - `WatchAcked` is credit-based: the viewer acknowledges what it has consumed and the
//!   server has at most `window` messages unacknowledged, so a slow viewer gets the latest
//!   frame when it is ready for one, never a backlog.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use tokio::sync::{mpsc, watch};
use tokio_stream::Stream;
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status, Streaming};
use vademecum_proto::v1 as pb;

use crate::auth::{Caller, caller};
use crate::convert;
use crate::registry::{Entry, Registry, StreamGuard, StreamKind, StreamPermit};
use crate::session::Frame;

/// Frame rate when the request leaves it at 0 (Hz).
pub const DEFAULT_RATE_HZ: f64 = 30.0;

/// The slowest rate a viewer may ask for (Hz): a frame or heartbeat at least every ten
/// seconds, so that a viewer stream never holds its slot while sending nothing.
pub const MIN_RATE_HZ: f64 = 0.1;

/// `WatchAcked`'s window when the request leaves it at 0: one message being read, one on
/// its way — full rate on a network whose round trip is under a frame period, and a frame
/// at most one period plus one message's processing old.
pub const DEFAULT_WINDOW: u32 = 2;

/// The largest window a viewer may ask for (each message in flight may be a whole frame).
pub const MAX_WINDOW: u32 = 16;

/// The Viewing service.
#[derive(Debug, Clone)]
pub struct ViewingService {
    /// The sessions.
    pub registry: Registry,
}

type FrameStream = Pin<Box<dyn Stream<Item = Result<pb::Frame, Status>> + Send>>;

/// What one viewer stream sends: the session's latest frame when it is new, else a
/// heartbeat, numbered per stream.
struct Pacer {
    entry: Arc<Entry>,
    frames: watch::Receiver<Arc<Frame>>,
    /// The viewer's rate, asked of the session's frame thread while it watches.
    _demand: crate::session::demand::DemandGuard,
    /// The session frame last sent.
    last: u64,
    /// Frames (with displacements) sent.
    sent: u64,
    /// The next message's number (0: the geometry).
    message: u64,
}

impl Pacer {
    fn new(entry: Arc<Entry>, rate_hz: f64) -> Self {
        let (frames, demand) = entry.session.subscribe_frames_at(rate_hz);
        Self {
            entry,
            frames,
            _demand: demand,
            last: 0,
            sent: 0,
            message: 0,
        }
    }

    /// The first message: the reference geometry.
    fn geometry(&mut self) -> pb::Frame {
        self.message = 1;
        convert::geometry_frame(self.entry.session.geometry())
    }

    /// The next message: a frame if the session has a new one, else a heartbeat.
    fn next(&mut self) -> pb::Frame {
        let f = self.frames.borrow_and_update().clone();
        let mut msg = if f.seq > self.last {
            self.last = f.seq;
            self.sent += 1;
            convert::frame(&f, self.sent)
        } else {
            // the tissue's step now (frames and answers carry steps), the session's time
            let s = &self.entry.session;
            let (ticks, steps) = (s.stats().ticks.load(Ordering::Relaxed), s.stats().steps.load(Ordering::Relaxed));
            convert::heartbeat(
                &f,
                self.sent,
                steps.saturating_sub(1).max(f.tick),
                ticks as f64 * s.config().period.as_secs_f64(),
            )
        };
        msg.message = self.message;
        self.message += 1;
        msg
    }
}

impl ViewingService {
    /// Checks a watch request and opens a viewer stream on its session: the session, the
    /// rate (Hz) and the stream's permit.
    fn open(&self, owner: &Caller, r: &pb::WatchRequest) -> Result<(Arc<Entry>, f64, StreamPermit), Status> {
        if !r.rate_hz.is_finite() || (r.rate_hz != 0.0 && r.rate_hz < MIN_RATE_HZ) {
            return Err(Status::invalid_argument(format!(
                "rate_hz must be 0 (the default, {DEFAULT_RATE_HZ} Hz) or at least {MIN_RATE_HZ} Hz, got {}",
                r.rate_hz
            )));
        }
        let cap = self.registry.config().max_frame_rate_hz;
        let rate = if r.rate_hz == 0.0 { DEFAULT_RATE_HZ } else { r.rate_hz.min(cap) };
        let entry = self.registry.get(owner, &r.session_id)?;
        let permit = self.registry.open_stream(owner, StreamKind::Watch)?;
        Ok((entry, rate, permit))
    }
}

/// A timer at the viewer's rate that skips the periods it missed.
fn pace(rate_hz: f64) -> tokio::time::Interval {
    let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / rate_hz));
    every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    every
}

/// The next control of an acknowledged stream; never, for a plain one.
async fn next_control(controls: &mut Option<Streaming<pb::ViewerControl>>) -> Result<Option<pb::ViewerControl>, Status> {
    match controls {
        Some(c) => c.message().await,
        None => std::future::pending().await,
    }
}

/// Serves one viewer stream until it or its session ends: the geometry, then a message per
/// period of `rate` Hz. With `controls` (WatchAcked), at most `window` messages are
/// unacknowledged; without (Watch), a period is skipped when the transport is behind.
async fn serve(
    entry: Arc<Entry>,
    rate: f64,
    permit: StreamPermit,
    tx: mpsc::Sender<Result<pb::Frame, Status>>,
    mut controls: Option<Streaming<pb::ViewerControl>>,
    window: u64,
) {
    use pb::viewer_control::Control;
    let _permit = permit;
    let _guard = StreamGuard::new(&entry.viewers);
    let mut closed = entry.closed.subscribe();
    let mut pacer = Pacer::new(entry.clone(), rate);
    if tx.send(Ok(pacer.geometry())).await.is_err() {
        return;
    }
    // messages acknowledged: every number below `acked`
    let mut acked = 0u64;
    let mut every = pace(rate);
    loop {
        tokio::select! {
            _ = every.tick() => {
                if controls.is_some() && pacer.message - acked >= window {
                    continue; // no credit: this period's frame is dropped here
                }
                match tx.try_reserve() {
                    Ok(slot) => slot.send(Ok(pacer.next())),
                    Err(mpsc::error::TrySendError::Full(())) => {} // skipped: the transport is behind
                    Err(mpsc::error::TrySendError::Closed(())) => return,
                }
            }
            m = next_control(&mut controls) => match m {
                Ok(Some(pb::ViewerControl { control: Some(Control::Ack(n)) })) => {
                    if n >= pacer.message {
                        let _ = tx.send(Err(Status::invalid_argument(format!(
                            "ack {n} names a message not sent yet (the last sent is {})",
                            pacer.message - 1
                        )))).await;
                        return;
                    }
                    acked = acked.max(n + 1);
                }
                Ok(Some(_)) => {
                    let _ = tx
                        .send(Err(Status::invalid_argument("after `start`, a viewer sends only acks")))
                        .await;
                    return;
                }
                // the viewer is done, or has gone
                Ok(None) | Err(_) => return,
            },
            _ = closed.changed() => return,
            _ = tx.closed() => return,
        }
    }
}

#[tonic::async_trait]
impl pb::viewing_server::Viewing for ViewingService {
    type WatchStream = FrameStream;
    type WatchAckedStream = FrameStream;

    async fn watch(&self, req: Request<pb::WatchRequest>) -> Result<Response<Self::WatchStream>, Status> {
        let owner = caller(&req)?;
        let (entry, rate, permit) = self.open(&owner, req.get_ref())?;
        let (tx, rx) = mpsc::channel(2);
        tokio::spawn(serve(entry, rate, permit, tx, None, 0));
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }

    async fn watch_acked(&self, req: Request<Streaming<pb::ViewerControl>>) -> Result<Response<Self::WatchAckedStream>, Status> {
        use pb::viewer_control::Control;
        let owner = caller(&req)?;
        let mut inbound = req.into_inner();
        let first = inbound
            .message()
            .await?
            .ok_or_else(|| Status::invalid_argument("the stream ended before its start message"))?;
        let Some(Control::Start(r)) = first.control else {
            return Err(Status::invalid_argument(
                "the first message of WatchAcked must be `start` (a WatchRequest)",
            ));
        };
        let window = match r.window {
            0 => DEFAULT_WINDOW,
            w if w <= MAX_WINDOW => w,
            w => {
                return Err(Status::invalid_argument(format!(
                    "window must be at most {MAX_WINDOW} messages, got {w}"
                )));
            }
        };
        let (entry, rate, permit) = self.open(&owner, &r)?;
        let (tx, rx) = mpsc::channel(2);
        tokio::spawn(serve(entry, rate, permit, tx, Some(inbound), u64::from(window)));
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }
}
