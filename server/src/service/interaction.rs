//! `vademecum.v1.Interaction`: tool states in, one response each, in order.
//!
//! Each stream gets a task that reads tool states, submits them to the session's tick
//! thread (bounded queue, refused at once when full) and forwards the tick's answers. The
//! answers come back through a stream of answers of this stream alone (the session's answer
//! ring and dispatcher: see [`crate::session::answers`]), in submission order.

use std::pin::Pin;
use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::sync::mpsc;
use tokio_stream::Stream;
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status, Streaming};
use vademecum_proto::v1 as pb;

use crate::auth::caller;
use crate::convert;
use crate::registry::{Entry, Registry, StreamGuard, StreamKind};
use crate::session::{StreamId, SubmitError, ToolCommand};

/// Answers still in flight when the client closes its side, or when the session closes, are
/// awaited this long at most.
const DRAIN: Duration = Duration::from_secs(2);

/// When a session closes under a stream, the states still arriving are counted as unanswered
/// until the client pauses this long (or for [`DRAIN`] at most). Long enough that a client
/// descheduled for a few time slices on a loaded machine is not taken for one that stopped:
/// its states then still count.
const INBOUND_PAUSE: Duration = Duration::from_millis(300);

/// Answers a stream holds before its consumer reads them (beyond: dropped, counted).
const ANSWER_CAPACITY: usize = 4096;

/// The Interaction service.
#[derive(Debug, Clone)]
pub struct InteractionService {
    /// The sessions.
    pub registry: Registry,
}

type ResponseStream = Pin<Box<dyn Stream<Item = Result<pb::ToolResponse, Status>> + Send>>;

#[tonic::async_trait]
impl pb::interaction_server::Interaction for InteractionService {
    type InteractStream = ResponseStream;

    async fn interact(&self, req: Request<Streaming<pb::ToolState>>) -> Result<Response<Self::InteractStream>, Status> {
        let owner = caller(&req)?;
        let mut inbound = req.into_inner();
        let first = inbound
            .message()
            .await?
            .ok_or_else(|| Status::invalid_argument("the stream ended before its first tool state"))?;
        if first.session_id.is_empty() {
            return Err(Status::invalid_argument("the first tool state must carry the session_id"));
        }
        let entry = self.registry.get(&owner, &first.session_id)?;
        let permit = self.registry.open_stream(&owner, StreamKind::Interact)?;
        let (out, rx) = mpsc::channel(256);
        tokio::spawn(async move {
            pump(entry, inbound, first, out).await;
            drop(permit);
        });
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }
}

/// Ends a stream whose session closed with `pending` tool states unanswered: ABORTED,
/// saying how many (none: the stream just ends).
async fn fail_pending(out: &mpsc::Sender<Result<pb::ToolResponse, Status>>, pending: u64) {
    if pending > 0 {
        let _ = out
            .send(Err(Status::aborted(format!(
                "the session was closed: the last {pending} tool state(s) sent were not answered"
            ))))
            .await;
    }
}

/// Why a tool kind cannot go on this stream at all (the stream ends with this status).
fn refused_kind(entry: &Entry, m: &pb::ToolState) -> Status {
    let named = match pb::ToolKind::try_from(m.kind) {
        Ok(k) => k.as_str_name().to_string(),
        Err(_) => format!("{} (not a ToolKind)", m.kind),
    };
    let tools: Vec<String> = entry.session.scene().spec.tools.iter().map(|t| format!("'{}'", t.name())).collect();
    Status::invalid_argument(format!(
        "tool kind {named} is not simulated by this session (effects: {}; its scene's tools: {})",
        entry.session.effects().join(", "),
        tools.join(", ")
    ))
}

/// Submits a tool state to the session's tick thread. `Err(Some(status))` ends the stream
/// with that status (a tool kind the scene does not simulate, a tool name it does not have,
/// a full queue); `Err(None)`
/// ends it quietly (the session has stopped).
fn submit(entry: &Entry, m: &pb::ToolState, reply: StreamId) -> Result<(), Option<Status>> {
    let input = convert::tool_input(m, &entry.session.scene().spec.tools).map_err(|e| Some(Status::invalid_argument(e.to_string())))?;
    if !entry.session.accepts(input.kind) {
        return Err(Some(refused_kind(entry, m)));
    }
    entry
        .session
        .submit(ToolCommand {
            input,
            seq: m.seq,
            client_time_us: m.client_time_us,
            received: Instant::now(),
            reply,
            named: !m.tool.is_empty(),
        })
        .map_err(|e| match e {
            SubmitError::Busy => Some(Status::resource_exhausted(e.to_string())),
            SubmitError::Closed => None,
        })
}

/// Reads tool states, submits them, forwards answers; ends when the client is done and
/// answered, the client goes away, or the session closes.
async fn pump(
    entry: Arc<Entry>,
    mut inbound: Streaming<pb::ToolState>,
    first: pb::ToolState,
    out: mpsc::Sender<Result<pb::ToolResponse, Status>>,
) {
    let _guard = StreamGuard::new(&entry.interacting);
    let Ok(mut answers) = entry.session.open_answers(ANSWER_CAPACITY) else {
        return; // the session has stopped
    };
    let reply = answers.id();
    let mut closed = entry.closed.subscribe();
    let id = first.session_id.clone();
    if let Err(status) = submit(&entry, &first, reply) {
        if let Some(s) = status {
            let _ = out.send(Err(s)).await;
        }
        return;
    }
    let (mut sent, mut answered) = (1u64, 0u64);
    // set when the client closes its side: the answers still in flight are awaited until then
    let mut drain_until: Option<tokio::time::Instant> = None;
    loop {
        if drain_until.is_some() && answered == sent {
            return;
        }
        tokio::select! {
            m = inbound.message(), if drain_until.is_none() => match m {
                Ok(Some(m)) => {
                    if !m.session_id.is_empty() && m.session_id != id {
                        let _ = out.send(Err(Status::invalid_argument("a stream acts on one session; its session_id cannot change"))).await;
                        return;
                    }
                    if let Err(status) = submit(&entry, &m, reply) {
                        if let Some(s) = status {
                            let _ = out.send(Err(s)).await;
                        }
                        return;
                    }
                    sent += 1;
                }
                Ok(None) => drain_until = Some(tokio::time::Instant::now() + DRAIN),
                Err(status) => {
                    // a malformed message, or the client went away
                    let _ = out.send(Err(status)).await;
                    return;
                }
            },
            a = answers.recv() => match a {
                Some(a) => {
                    answered += 1;
                    if out.send(Ok(convert::tool_response(&a))).await.is_err() {
                        return;
                    }
                }
                None => {
                    fail_pending(&out, sent - answered).await;
                    return;
                }
            },
            _ = closed.changed() => {
                // the tick thread stops within a tick and the dispatcher then delivers every
                // answer it computed and ends the stream of answers: forward them all, then
                // fail the rest with a status
                let until = tokio::time::Instant::now() + DRAIN;
                while let Ok(Some(a)) = tokio::time::timeout_at(until, answers.recv()).await {
                    answered += 1;
                    if out.send(Ok(convert::tool_response(&a))).await.is_err() {
                        return;
                    }
                }
                // the states the client sent before the close that this stream had not read
                // yet are unanswered too: count those that arrive without a pause
                if drain_until.is_none() {
                    let until = tokio::time::Instant::now() + DRAIN;
                    while let Ok(Ok(Some(_))) = tokio::time::timeout(INBOUND_PAUSE, inbound.message()).await {
                        sent += 1;
                        if tokio::time::Instant::now() >= until {
                            break;
                        }
                    }
                }
                fail_pending(&out, sent - answered).await;
                return;
            }
            _ = tokio::time::sleep_until(drain_until.unwrap_or_else(tokio::time::Instant::now)), if drain_until.is_some() => return,
        }
    }
}
