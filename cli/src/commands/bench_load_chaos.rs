//! Chaos for `vademecum bench load`: clients that run as processes of their own, so they can be
//! killed with SIGKILL (`kill -9`) as a crashed frontend would die — its socket reset by the
//! OS, nothing said to the server.
//!
//! A chaos client is `vademecum bench load-client` (hidden): one interaction stream on a
//! session, a tool state every period (each after the previous answer), printing its account
//! (`sent answered refused`) on stdout after every state sent and every answer, and ending
//! when its stdin closes. The parent keeps the last account each printed, so a client killed
//! mid-stream is accounted for to the state: what it sent is answered, refused, or was in flight
//! (at most one) when it died.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::Context;

use super::bench_load_client::{ClientAccount, Drive, client};
use crate::cli::LoadClientArgs;

/// `vademecum bench load-client`: one chaos client (module docs).
pub fn run(a: LoadClientArgs) -> anyhow::Result<ExitCode> {
    if !(a.rate > 0.0 && a.rate <= 2000.0) {
        anyhow::bail!("--rate must lie in (0, 2000] Hz, got {}", a.rate);
    }
    let stop = Arc::new(AtomicBool::new(false));
    {
        // the parent closes our stdin to end us
        let stop = stop.clone();
        std::thread::spawn(move || {
            let _ = std::io::stdin().read_to_end(&mut Vec::new());
            stop.store(true, Ordering::Relaxed);
        });
    }
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let period = Duration::from_secs_f64(1.0 / a.rate);
    let report = Box::new(|acc: &ClientAccount| print_account(acc));
    let account = rt.block_on(client(a.addr, a.session, Drive::Probe, period, stop, report));
    print_account(&account);
    Ok(ExitCode::SUCCESS)
}

fn print_account(acc: &ClientAccount) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{} {} {}", acc.sent, acc.answered, acc.refused);
    let _ = out.flush();
}

/// One chaos client process and the last account it printed.
struct ChaosClient {
    session: String,
    child: Child,
    last: Arc<Mutex<[u64; 3]>>,
    reader: JoinHandle<()>,
}

/// What the chaos clients did, killed ones included.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct ChaosAccount {
    pub sent: u64,
    pub answered: u64,
    pub refused: u64,
    /// States sent by a killed client and not yet answered when it died.
    pub in_flight_at_kill: u64,
    /// Clients killed.
    pub kills: u64,
}

/// The chaos clients of a run.
pub(super) struct Chaos {
    clients: Vec<ChaosClient>,
    account: ChaosAccount,
    addr: String,
    rate: f64,
    /// xorshift state choosing the victims.
    rng: u64,
}

impl Chaos {
    /// A client process for each session of `sessions`, on the server at `addr`.
    pub fn start(addr: &str, sessions: &[String], rate: f64) -> anyhow::Result<Self> {
        let seed = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0x9E37_79B9, |d| d.as_nanos() as u64);
        let mut chaos = Self {
            clients: Vec::new(),
            account: ChaosAccount::default(),
            addr: addr.to_string(),
            rate,
            rng: seed | 1,
        };
        for s in sessions {
            let c = chaos.spawn(s)?;
            chaos.clients.push(c);
        }
        Ok(chaos)
    }

    fn spawn(&self, session: &str) -> anyhow::Result<ChaosClient> {
        let exe = std::env::current_exe().context("cannot find this executable to start a client")?;
        let mut child = Command::new(exe)
            .args(["bench", "load-client", "--addr", &self.addr, "--session", session])
            .args(["--rate", &self.rate.to_string()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start a chaos client")?;
        let stdout = child.stdout.take().context("the chaos client's output")?;
        let last = Arc::new(Mutex::new([0u64; 3]));
        let reader = {
            let last = last.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    let v: Vec<u64> = line.split_whitespace().filter_map(|x| x.parse().ok()).collect();
                    if let [sent, answered, refused] = v[..] {
                        *last.lock().unwrap_or_else(|e| e.into_inner()) = [sent, answered, refused];
                    }
                }
            })
        };
        Ok(ChaosClient {
            session: session.to_string(),
            child,
            last,
            reader,
        })
    }

    /// Adds a finished client's last account.
    fn settle(&mut self, c: ChaosClient, killed: bool) {
        let _ = c.reader.join();
        let [sent, answered, refused] = *c.last.lock().unwrap_or_else(|e| e.into_inner());
        self.account.sent += sent;
        self.account.answered += answered;
        self.account.refused += refused;
        if killed {
            self.account.kills += 1;
            self.account.in_flight_at_kill += sent.saturating_sub(answered + refused);
        }
    }

    /// Kills a client chosen at random with SIGKILL and starts a new one on its session;
    /// returns the session.
    pub fn kill_one(&mut self) -> anyhow::Result<String> {
        if self.clients.is_empty() {
            anyhow::bail!("no chaos client to kill");
        }
        self.rng ^= self.rng << 13;
        self.rng ^= self.rng >> 7;
        self.rng ^= self.rng << 17;
        let k = (self.rng % self.clients.len() as u64) as usize;
        let mut victim = self.clients.swap_remove(k);
        // std's kill is SIGKILL on Unix
        let _ = victim.child.kill();
        let _ = victim.child.wait();
        let session = victim.session.clone();
        self.settle(victim, true);
        let fresh = self.spawn(&session)?;
        self.clients.push(fresh);
        Ok(session)
    }

    /// Ends every client (closing its stdin) and returns the account of them all.
    pub fn finish(mut self) -> ChaosAccount {
        for mut c in std::mem::take(&mut self.clients) {
            drop(c.child.stdin.take());
            let _ = c.child.wait();
            self.settle(c, false);
        }
        self.account
    }
}

impl Drop for Chaos {
    fn drop(&mut self) {
        for c in &mut self.clients {
            let _ = c.child.kill();
            let _ = c.child.wait();
        }
    }
}

/// The device bridges of `bench load --haptic K`: a `vademecum-bridge` process per haptic
/// session, its simulated stylus following `script`; one can be killed and restarted.
pub(super) struct Bridges {
    exe: std::path::PathBuf,
    script: std::path::PathBuf,
    seconds: f64,
    answer_wake: vademecum_bridge::bridge_loop::AnswerWake,
    children: Vec<(String, Child)>,
    /// Bridges killed.
    pub kills: u64,
}

impl Bridges {
    /// A bridge on each of `channels`, running for `seconds` at most: the executable `exe`, or
    /// `vademecum-bridge` beside this one.
    pub fn start(
        exe: Option<&std::path::Path>,
        channels: &[String],
        script: &std::path::Path,
        seconds: f64,
        answer_wake: vademecum_bridge::bridge_loop::AnswerWake,
    ) -> anyhow::Result<Self> {
        let exe = match exe {
            Some(e) => e.to_path_buf(),
            None => std::env::current_exe()
                .context("cannot find this executable")?
                .with_file_name("vademecum-bridge"),
        };
        if !exe.exists() {
            anyhow::bail!(
                "--haptic needs the device bridge at {}: build it with `cargo build --release -p vademecum-bridge`, or say where it is with --bridge",
                exe.display()
            );
        }
        let mut b = Self {
            exe,
            script: script.to_path_buf(),
            seconds,
            answer_wake,
            children: Vec::new(),
            kills: 0,
        };
        for c in channels {
            let child = b.spawn(c)?;
            b.children.push((c.clone(), child));
        }
        Ok(b)
    }

    /// A bridge on `channel`: a simulated stylus, sleeping to its deadlines (many bridges
    /// share the host's cores: no spinning), waiting for its answers as asked.
    fn spawn(&self, channel: &str) -> anyhow::Result<Child> {
        Command::new(&self.exe)
            .args(["--session", channel, "--device", "sim", "--script"])
            .arg(&self.script)
            .args(["--wait", "sleep", "--duration", &format!("{:.1}", self.seconds)])
            .args(["--answer-wake", &self.answer_wake.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start a device bridge")
    }

    /// Kills the first bridge with SIGKILL and starts a new one on its channel.
    pub fn kill_one(&mut self) -> anyhow::Result<()> {
        let Some((channel, child)) = self.children.first_mut() else {
            return Ok(());
        };
        let _ = child.kill();
        let _ = child.wait();
        self.kills += 1;
        let channel = channel.clone();
        let fresh = self.spawn(&channel)?;
        self.children[0].1 = fresh;
        Ok(())
    }

    /// Stops every bridge (SIGTERM: each fades its force and exits).
    pub fn finish(mut self) {
        for (_, c) in &mut self.children {
            // SAFETY: kill(2) with a child's pid and a valid signal has no memory effects.
            unsafe { libc::kill(c.id() as libc::pid_t, libc::SIGTERM) };
        }
        for (_, c) in &mut self.children {
            let _ = c.wait();
        }
        self.children.clear();
    }
}

impl Drop for Bridges {
    fn drop(&mut self) {
        for (_, c) in &mut self.children {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
