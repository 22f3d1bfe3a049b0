//! The force log of a headless run (`forces.csv`), written by a thread of its own as the
//! session's answers arrive, and what the run's summary reads of it: the peak force, the ticks
//! in contact, the blade's force and events, the grasp's events.
//!
//! Columns: `tick, t_s, x_m, y_m, z_m` (the contact point), `fx_n, fy_n, fz_n`, `contact`,
//! `depth_m`, `events` (their names), `latency_us`, `force_error_n`; a cutting session adds
//! `f_perp_n, f_par_n, cutting`, a tearing one `closure` (the jaws' script). A run of several
//! hands writes a row per hand each tick, in the hands' order, with `tool` (the tool's name)
//! after `tick`; a hand's row leaves the other tools' columns empty (a grasper has no blade).

use std::path::PathBuf;
use std::thread::JoinHandle;

use anyhow::Context;
use vademecum_engine::pipeline::Events;
use vademecum_server::session::{Answer, Trajectory};

use super::hands::HandKind;
use super::{BladeRow, TearSummary};

/// What the force log saw, for the summary.
#[derive(Default)]
pub(super) struct ForceLog {
    /// The largest force magnitude (N) and when (s).
    pub peak_n: f64,
    pub peak_t_s: f64,
    /// Ticks in contact.
    pub contact_ticks: u64,
    /// Ticks cutting, strokes started, cuts swapped in.
    pub cut_counts: [u64; 3],
    /// The blade's force at each scalpel tick (the blade plot).
    pub blade_rows: Vec<BladeRow>,
    /// The grasp's events (the damage is the frames').
    pub tear: TearSummary,
    /// The last force magnitude, the one at which the tissue tears.
    last_force_n: f64,
}

/// One hand's answers, as the log writes them.
pub(super) struct LoggedHand {
    pub answers: tokio::sync::mpsc::Receiver<Answer>,
    /// The tool's name: a `tool` column when the run has several hands.
    pub tool: String,
    /// The blade's columns are this hand's (the scalpel's, in a cutting session).
    pub cutting: bool,
    /// The jaws' script: the closure column is this hand's (the grasper's, tearing).
    pub jaws: Option<Trajectory>,
}

/// Writes every answer of `hands` to `path` as it arrives, on a thread of its own (the
/// session's tick never waits for the file); `period_s` numbers a script's answers in time.
/// Several hands are answered in the same periods: each period's rows, one per hand, in the
/// hands' order, with a `tool` column. Returns what each hand's rows saw.
pub(super) fn spawn(path: PathBuf, mut hands: Vec<LoggedHand>, period_s: f64) -> JoinHandle<anyhow::Result<Vec<ForceLog>>> {
    std::thread::spawn(move || {
        let mut w = csv::Writer::from_path(&path).with_context(|| format!("cannot write {}", path.display()))?;
        let columns = Columns {
            tool: hands.len() > 1,
            blade: hands.iter().any(|h| h.cutting),
            jaws: hands.iter().any(|h| h.jaws.is_some()),
        };
        w.write_record(columns.header())?;
        let mut logs: Vec<ForceLog> = hands.iter().map(|_| ForceLog::default()).collect();
        'periods: loop {
            for (h, log) in hands.iter_mut().zip(&mut logs) {
                let Some(a) = h.answers.blocking_recv() else {
                    break 'periods;
                };
                // a script's answer is numbered with its period (`Script`)
                let t_s = a.seq as f64 * period_s;
                log.add(&a, t_s);
                w.write_record(columns.record(&a, t_s, h))?;
            }
        }
        w.flush()?;
        Ok(logs)
    })
}

/// The log's columns: the base ones, a hand's tool, the blade's and the jaws'.
struct Columns {
    tool: bool,
    blade: bool,
    jaws: bool,
}

impl Columns {
    fn header(&self) -> Vec<&'static str> {
        let mut header = vec!["tick"];
        if self.tool {
            header.push("tool");
        }
        header.extend([
            "t_s",
            "x_m",
            "y_m",
            "z_m",
            "fx_n",
            "fy_n",
            "fz_n",
            "contact",
            "depth_m",
            "events",
            "latency_us",
            "force_error_n",
        ]);
        if self.blade {
            header.extend(["f_perp_n", "f_par_n", "cutting"]);
        }
        if self.jaws {
            header.push("closure");
        }
        header
    }

    /// One answer's row, of hand `h`: the columns of the other hands' tools left empty.
    fn record(&self, a: &Answer, t_s: f64, h: &LoggedHand) -> Vec<String> {
        let (f, c) = (a.state.force_n, a.state.contact);
        let p = c.map_or([f64::NAN; 3], |c| c.point_m);
        let mut record = vec![a.seq.to_string()];
        if self.tool {
            record.push(h.tool.clone());
        }
        record.extend([
            format!("{t_s:.6}"),
            format!("{:e}", p[0]),
            format!("{:e}", p[1]),
            format!("{:e}", p[2]),
            format!("{:e}", f[0]),
            format!("{:e}", f[1]),
            format!("{:e}", f[2]),
            u8::from(a.state.events.has(Events::CONTACT)).to_string(),
            format!("{:e}", c.map_or(0.0, |c| c.depth_m)),
            a.state.events.names(),
            (a.answered_us - a.received_us).to_string(),
            a.state.force_error_n.map_or(String::new(), |e| format!("{e:e}")),
        ]);
        if self.blade {
            record.extend(match a.state.blade.filter(|_| h.cutting) {
                Some(b) => [
                    format!("{:e}", magnitude(b.perpendicular_n)),
                    format!("{:e}", magnitude(b.parallel_n)),
                    u8::from(b.cutting).to_string(),
                ],
                None => [String::new(), String::new(), String::new()],
            });
        }
        if self.jaws {
            record.push(h.jaws.as_ref().map_or(String::new(), |t| format!("{}", t.at(t_s).closure)));
        }
        record
    }
}

fn magnitude(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

impl ForceLog {
    /// Adds the log of one hand of several moving a tool of `kind`: the largest peak, the
    /// answers in contact summed, the blade's figures from the scalpel's hand and the grasp's
    /// from the grasper's.
    pub fn merge(&mut self, other: ForceLog, kind: HandKind) {
        if other.peak_n > self.peak_n {
            (self.peak_n, self.peak_t_s) = (other.peak_n, other.peak_t_s);
        }
        self.contact_ticks += other.contact_ticks;
        match kind {
            HandKind::Scalpel => (self.cut_counts, self.blade_rows) = (other.cut_counts, other.blade_rows),
            HandKind::Grasper => self.tear = other.tear,
            HandKind::Probe => {}
        }
    }

    /// Counts answer `a`, served at `t_s`.
    fn add(&mut self, a: &Answer, t_s: f64) {
        let ev = a.state.events;
        let force = magnitude(a.state.force_n);
        if force > self.peak_n {
            (self.peak_n, self.peak_t_s) = (force, t_s);
        }
        self.contact_ticks += u64::from(a.state.contact.is_some() || ev.has(Events::CONTACT));
        let tear = &mut self.tear;
        for (at, flag) in [
            (&mut tear.grasped_at_s, Events::GRASPED),
            (&mut tear.released_at_s, Events::RELEASED),
        ] {
            if at.is_none() && ev.has(flag) {
                *at = Some(t_s);
            }
        }
        if tear.torn_at_s.is_none() && ev.has(Events::TISSUE_TORN) {
            tear.torn_at_s = Some(t_s);
            tear.force_at_tear_n = Some(self.last_force_n);
        }
        tear.tearing_ticks += u64::from(ev.has(Events::TEARING));
        self.last_force_n = force;
        let blade = a.state.blade;
        self.cut_counts[0] += u64::from(blade.is_some_and(|b| b.cutting));
        self.cut_counts[1] += u64::from(ev.has(Events::CUT_STARTED));
        self.cut_counts[2] += u64::from(ev.has(Events::CUT_ADVANCED));
        if let Some(b) = blade {
            self.blade_rows.push(BladeRow {
                t_s,
                parallel_n: magnitude(b.parallel_n),
                perpendicular_n: magnitude(b.perpendicular_n),
                advanced: ev.has(Events::CUT_ADVANCED),
            });
        }
    }
}
