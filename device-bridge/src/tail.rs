//! Where a late haptic answer lost its time: every tick of a bridge trace whose device read →
//! force written took longer than [`LATE_NS`], or whose force did not answer its own state,
//! sorted into one cause from the timestamps both sides recorded (the bridge's read, publish
//! and write; the server's planned wake, first poll, receipt and answer — all
//! `CLOCK_MONOTONIC`, one clock for both processes).
//!
//! The causes, tested in this order (the first that fits names the tick):
//!
//! | cause | the timestamps show |
//! |---|---|
//! | `bridge publish` | the bridge took more than [`SLOW_NS`] from its read to the state published |
//! | `bridge woke late` | the bridge woke for the tick later than the server's spin window is wide, so its state came after the server had stopped polling for it |
//! | `no answer seen` | no answer to this state reached the bridge within the next ticks (the server answered a newer state first), so the server's times are unknown |
//! | `peer woke late` | the server polled more than [`SLOW_NS`] after it meant to (the OS woke it late) and after the state was sent |
//! | `peer window late` | the server meant to start polling only after the state was sent (its predicted phase was late) |
//! | `peer saw it late` | the server was polling when the state was sent but received it more than [`SLOW_NS`] later (preempted while polling, or delivery) |
//! | `peer answered late` | more than [`SLOW_NS`] from receipt to answer (the tick's work, or preempted) |
//! | `bridge stopped waiting` | the answer came after the bridge's own wait for it had ended, so it was used a tick late |
//! | `bridge saw it late` | the answer was published in time but the bridge wrote the force more than [`SLOW_NS`] later (the bridge preempted) |
//! | `other` | none of the above (small delays adding up) |

use vademecum_proto::shm::HapticCommand;

use crate::bridge_loop::TraceRow;

/// A tick is late when its device read → force written exceeds this (ns).
pub const LATE_NS: u64 = 100_000;

/// One step of the path is slow when it takes more than this (ns).
pub const SLOW_NS: u64 = 50_000;

/// The causes of a late tick, in the order they are tested (see the [module docs](self)).
pub const CAUSES: [&str; 10] = [
    "bridge publish",
    "bridge woke late",
    "no answer seen",
    "peer woke late",
    "peer window late",
    "peer saw it late",
    "peer answered late",
    "bridge stopped waiting",
    "bridge saw it late",
    "other",
];

/// The late ticks of a trace, counted by cause.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct TailCauses {
    /// Ticks traced.
    pub ticks: u64,
    /// Late ticks (read → write over [`LATE_NS`], or not answering their own state).
    pub late: u64,
    /// Late ticks per cause, in [`CAUSES`] order.
    pub counts: [u64; CAUSES.len()],
}

impl TailCauses {
    /// The causes as (name, count) pairs with a non-zero count.
    pub fn named(&self) -> Vec<(&'static str, u64)> {
        CAUSES.iter().copied().zip(self.counts).filter(|&(_, n)| n > 0).collect()
    }
}

/// The server's times for one state, from the row whose force answered it.
#[derive(Debug, Clone, Copy)]
struct PeerTimes {
    planned: u64,
    polling: u64,
    received: u64,
    answer: u64,
}

/// Sorts the late ticks of `trace` by cause. `late_answers` are the answers that reached the
/// bridge after their own tick ([`BridgeOutcome::late_answers`](crate::bridge_loop::BridgeOutcome::late_answers));
/// `answer_wait_ns` is how long the bridge polled for each answer, `peer_window_ns` the
/// server's spin window.
pub fn classify(trace: &[TraceRow], late_answers: &[HapticCommand], answer_wait_ns: u64, peer_window_ns: u64) -> TailCauses {
    let mut out = TailCauses {
        ticks: trace.len() as u64,
        ..TailCauses::default()
    };
    // the server's times for a state travel with the force that answers it, which may be
    // used at a later tick
    let peer_of = |tick: u64, from: usize| -> Option<PeerTimes> {
        let used = trace[from..]
            .iter()
            .take(8)
            .find(|r| r.answers == tick && r.t_answer_ns != 0)
            .map(|r| PeerTimes {
                planned: r.t_peer_planned_ns,
                polling: r.t_peer_polling_ns,
                received: r.t_peer_received_ns,
                answer: r.t_answer_ns,
            });
        used.or_else(|| {
            let i = late_answers.partition_point(|c| c.state_seq < tick);
            late_answers.get(i).filter(|c| c.state_seq == tick).map(|c| PeerTimes {
                planned: c.t_peer_planned_ns,
                polling: c.t_peer_polling_ns,
                received: c.t_peer_received_ns,
                answer: c.t_answer_ns,
            })
        })
    };
    for (i, r) in trace.iter().enumerate() {
        let own = r.answers == r.tick && r.t_answer_ns != 0;
        if own && r.t_write_ns.saturating_sub(r.t_read_ns) <= LATE_NS {
            continue;
        }
        out.late += 1;
        out.counts[cause(r, peer_of(r.tick, i), answer_wait_ns, peer_window_ns)] += 1;
    }
    out
}

/// The index in [`CAUSES`] of why row `r` was late.
fn cause(r: &TraceRow, peer: Option<PeerTimes>, answer_wait_ns: u64, peer_window_ns: u64) -> usize {
    if r.t_sent_ns.saturating_sub(r.t_read_ns) > SLOW_NS {
        return 0;
    }
    if r.lateness_ns > peer_window_ns {
        return 1;
    }
    let Some(p) = peer else {
        return 2;
    };
    let sent = r.t_sent_ns;
    if p.polling > sent && p.polling.saturating_sub(p.planned) > SLOW_NS {
        return 3;
    }
    if p.planned > sent {
        return 4;
    }
    if p.received.saturating_sub(sent.max(p.polling)) > SLOW_NS {
        return 5;
    }
    if p.answer.saturating_sub(p.received) > SLOW_NS {
        return 6;
    }
    if p.answer > sent + answer_wait_ns {
        return 7;
    }
    if r.answers == r.tick && r.t_write_ns.saturating_sub(p.answer) > SLOW_NS {
        return 8;
    }
    9
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tick read at `k` ms whose state went out 2 µs later, with the server's times given
    /// as offsets (µs) from the send, answered at its own tick and written `write` µs after
    /// the send.
    fn row(k: u64, peer: Option<[u64; 4]>, write: u64) -> TraceRow {
        let read = (k + 1000) * 1_000_000;
        let sent = read + 2_000;
        let mut r = TraceRow {
            tick: k,
            t_read_ns: read,
            t_sent_ns: sent,
            t_write_ns: sent + write * 1000,
            answers: k,
            ..TraceRow::default()
        };
        match peer {
            Some([planned, polling, received, answer]) => {
                r.t_peer_planned_ns = sent + planned * 1000 - 300_000;
                r.t_peer_polling_ns = sent + polling * 1000 - 300_000;
                r.t_peer_received_ns = sent + received * 1000;
                r.t_answer_ns = sent + answer * 1000;
            }
            None => r.answers = k.wrapping_sub(1),
        }
        r
    }

    #[test]
    fn each_late_tick_gets_the_cause_its_timestamps_show() {
        // offsets: planned and polling are given +300 µs (so 300 = at the send)
        let trace = [
            row(0, Some([100, 101, 1, 5]), 8),       // on time
            row(1, Some([100, 500, 201, 205]), 208), // woke 400 µs after planning
            row(2, Some([350, 351, 52, 55]), 120),   // planned after the send
            row(3, Some([100, 101, 90, 95]), 130),   // polling, saw it 90 µs late
            row(4, Some([100, 101, 1, 150]), 155),   // slow answer
            row(5, Some([100, 101, 1, 20]), 140),    // bridge wrote it 120 µs after the answer
            row(6, None, 1000),                      // never answered in time, nothing seen
            TraceRow {
                lateness_ns: 250_000, // the bridge woke 250 µs late, past the server's window
                ..row(7, None, 1000)
            },
        ];
        let c = classify(&trace, &[], 300_000, 200_000);
        assert_eq!((c.ticks, c.late), (8, 7));
        assert_eq!(
            c.named(),
            vec![
                ("bridge woke late", 1),
                ("no answer seen", 1),
                ("peer woke late", 1),
                ("peer window late", 1),
                ("peer saw it late", 1),
                ("peer answered late", 1),
                ("bridge saw it late", 1),
            ]
        );
    }

    #[test]
    fn an_answer_used_a_tick_late_is_traced_back_to_its_state() {
        let mut late = row(1, None, 1000);
        late.answers = 0;
        // tick 2 used the answer to tick 1, published 400 µs after tick 1's state was sent
        let mut next = row(2, Some([100, 101, 1, 5]), 8);
        next.answers = 1;
        next.t_peer_planned_ns = late.t_sent_ns - 200_000;
        next.t_peer_polling_ns = late.t_sent_ns - 199_000;
        next.t_peer_received_ns = late.t_sent_ns + 1_000;
        next.t_answer_ns = late.t_sent_ns + 400_000;
        let c = classify(&[row(0, Some([100, 101, 1, 5]), 8), late, next], &[], 300_000, 200_000);
        // tick 1: its answer, found at tick 2, took 399 µs from receipt to publication; tick 2
        // wrote that old force, and its own answer is not in the trace
        assert_eq!(c.late, 2);
        assert_eq!(c.named(), vec![("no answer seen", 1), ("peer answered late", 1)]);
    }

    #[test]
    fn a_superseded_answer_still_tells_the_servers_side() {
        // tick 1's answer arrived at tick 2 but was superseded by tick 2's own: only the
        // list of late answers has it — the server woke 400 µs after it meant to
        let late = row(1, None, 1000);
        let cmd = HapticCommand {
            state_seq: 1,
            t_peer_planned_ns: late.t_sent_ns - 200_000,
            t_peer_polling_ns: late.t_sent_ns + 200_000,
            t_peer_received_ns: late.t_sent_ns + 201_000,
            t_answer_ns: late.t_sent_ns + 205_000,
            ..HapticCommand::default()
        };
        let c = classify(
            &[row(0, Some([100, 101, 1, 5]), 8), late, row(2, Some([100, 101, 1, 5]), 8)],
            &[cmd],
            300_000,
            200_000,
        );
        assert_eq!(c.named(), vec![("peer woke late", 1)]);
    }
}
