//! The client side of `vademecum bench load`: one interaction stream driving a session (a
//! probe pressing, or a grasper pulling and letting go), with its account of the states sent,
//! answered, refused and lost — run by the bench in its own process and by the chaos clients
//! (`bench_load_chaos`) in theirs.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;

use super::bench_session::{bench_tool, hist};

/// What one client stream did.
#[derive(Debug, Default)]
pub(super) struct ClientAccount {
    pub sent: u64,
    pub answered: u64,
    /// Refused: the stream could not be opened, a send failed, or it ended with an error
    /// status (the state sent then is counted here, not answered).
    pub refused: u64,
    /// Answers in contact with the tissue (a probe touching it, a grasper holding it), and
    /// answers that say it tore.
    pub contact: u64,
    pub torn: u64,
    /// Round trips (µs) of the answered states.
    pub rtt: Option<Histogram<u64>>,
}

impl ClientAccount {
    /// A stream that could not be opened.
    fn refused() -> Self {
        Self {
            refused: 1,
            ..Self::default()
        }
    }
}

/// Session `id` on a connection of its own to `addr`, as a separate frontend has.
pub(super) async fn connect(addr: &str, id: &str) -> Option<vademecum_client::Session> {
    vademecum_client::Client::connect(addr.to_string())
        .await
        .ok()?
        .session(id)
        .await
        .ok()
}

/// What a load client's tool does, state after state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Drive {
    /// A probe circling over the built-in organ and pressing in and out ([`bench_path`]).
    Probe,
    /// A grasper closed on a grasp site's centre, pulling along the site's direction at `speed`
    /// (m/s) until the force reaches `force` (N) or the pull `reach` (m), then back to where
    /// it closed, over and over.
    Grasp {
        centre: [f64; 3],
        direction: [f64; 3],
        force: f64,
        speed: f64,
        reach: f64,
    },
}

impl Drive {
    /// The grasper's drive of a tearing session (`info`: its description; `size`: the organ's
    /// bounding-box diagonal, m): the first grasp site, pulled to half the grasper's max force
    /// (short of tearing the built-in scenes) at 5 % of the organ's size per second, at most
    /// a fifth of its size out. `None` without a grasper or a site.
    pub(super) fn grasp(info: &vademecum_client::pb::SessionInfo, size: f64) -> Option<Self> {
        let tool = info.tools.iter().find(|t| !t.grasp_sites.is_empty())?;
        let site = &tool.grasp_sites[0];
        let v = |v: &Option<vademecum_client::pb::Vec3>| v.as_ref().map(|v| [v.x, v.y, v.z]);
        Some(Self::Grasp {
            centre: v(&site.centre_m)?,
            direction: v(&site.pull_direction)?,
            force: 0.5 * tool.max_force_n,
            speed: 0.05 * size,
            reach: 0.2 * size,
        })
    }
}

/// A [`Drive`] in motion: where the grasper's pull is and which way it goes.
struct Driver {
    drive: Drive,
    /// Seconds between states.
    dt: f64,
    pull: f64,
    outward: bool,
}

impl Driver {
    fn new(drive: Drive, period: Duration) -> Self {
        Self {
            drive,
            dt: period.as_secs_f64(),
            pull: 0.0,
            outward: true,
        }
    }

    /// Tool state `i`, after an answer with force `force` (N, its magnitude) to the last.
    fn state(&mut self, i: u64, force: f64) -> vademecum_client::pb::ToolState {
        match self.drive {
            Drive::Probe => bench_tool(i),
            Drive::Grasp {
                centre,
                direction,
                force: most,
                speed,
                reach,
            } => {
                if self.outward && (force >= most || self.pull >= reach) {
                    self.outward = false;
                } else if !self.outward && self.pull <= 0.0 {
                    self.outward = true;
                }
                let step = speed * self.dt;
                self.pull = if self.outward {
                    self.pull + step
                } else {
                    (self.pull - step).max(0.0)
                };
                let at = std::array::from_fn(|k| centre[k] + self.pull * direction[k]);
                vademecum_client::grasper_at(i, at, 1.0)
            }
        }
    }
}

/// Called with a client's account after every state it sends and every answer.
pub(super) type Progress = Box<dyn FnMut(&ClientAccount) + Send>;

/// One interaction stream on a connection of its own: a tool state every `period` (each after
/// the previous answer), until `stop`; `progress` is told the account as it changes.
pub(super) async fn client(
    addr: String,
    id: String,
    drive: Drive,
    period: Duration,
    stop: Arc<AtomicBool>,
    mut progress: Progress,
) -> ClientAccount {
    let mut account = ClientAccount::default();
    let mut h = hist();
    let Some(session) = connect(&addr, &id).await else {
        return ClientAccount::refused();
    };
    let Ok(mut tools) = session.interact().await else {
        return ClientAccount::refused();
    };
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut i = 0u64;
    let (mut driver, mut force) = (Driver::new(drive, period), 0.0);
    while !stop.load(Ordering::Relaxed) {
        ticker.tick().await;
        let t0 = Instant::now();
        account.sent += 1;
        progress(&account);
        if tools.send(driver.state(i, force)).await.is_err() {
            account.refused += 1;
            break;
        }
        match tools.next().await {
            Ok(Some(r)) if r.seq == i => {
                force = r.force_n.map_or(0.0, |f| (f.x * f.x + f.y * f.y + f.z * f.z).sqrt());
                let has = |e: vademecum_client::pb::Event| r.events & e as u32 != 0;
                account.contact += u64::from(has(vademecum_client::pb::Event::Contact));
                account.torn += u64::from(has(vademecum_client::pb::Event::TissueTorn));
                account.answered += 1;
                progress(&account);
                let _ = h.record((t0.elapsed().as_nanos() as u64).max(1));
            }
            _ => {
                account.refused += 1;
                break;
            }
        }
        i += 1;
    }
    tools.finish();
    account.rtt = Some(h);
    account
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grasper's drive: closed on the site's centre, out along the pull direction at its
    /// speed until the answered force reaches the limit (or the pull its reach), back to the
    /// centre, and out again.
    #[test]
    fn the_grasp_drive_pulls_out_to_the_force_and_back_to_where_it_closed() {
        let drive = Drive::Grasp {
            centre: [1.0, 2.0, 3.0],
            direction: [0.0, 0.0, 1.0],
            force: 0.5,
            speed: 0.1,
            reach: 1.0,
        };
        let mut d = Driver::new(drive, Duration::from_millis(100));
        let z = |s: &vademecum_client::pb::ToolState| s.position_m.as_ref().map(|p| p.z).unwrap();
        let first = d.state(0, 0.0);
        assert_eq!(first.closure, 1.0);
        assert!((z(&first) - 3.01).abs() < 1e-12, "{first:?}");
        // out while the force stays under the limit
        for i in 1..5 {
            assert!((z(&d.state(i, 0.1)) - (3.0 + 0.01 * (i + 1) as f64)).abs() < 1e-12);
        }
        // the force reached: back, never past where it closed
        let back = d.state(5, 0.6);
        assert!((z(&back) - 3.04).abs() < 1e-12, "{back:?}");
        let mut last = z(&back);
        for i in 6..20 {
            let now = z(&d.state(i, 0.2));
            assert!(now <= last + 1e-12 && now >= 3.0 - 1e-12, "{now} after {last}");
            if now <= 3.0 + 1e-12 {
                // at the centre: out again
                assert!(z(&d.state(i + 1, 0.0)) > 3.0);
                return;
            }
            last = now;
        }
        panic!("the drive never came back");
    }

    #[test]
    fn the_probe_drive_is_the_benchmarks_path() {
        let mut d = Driver::new(Drive::Probe, Duration::from_millis(1));
        assert_eq!(d.state(7, 0.0), bench_tool(7));
    }
}
