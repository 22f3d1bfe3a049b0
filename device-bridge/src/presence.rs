//! Saying, once, when no server shares the bridge's channel. The bridge and the server meet in
//! iceoryx2's files (`/tmp/iceoryx2`, `/dev/shm`), which are 0600: a server under another user,
//! or behind a private `/tmp` (systemd's `PrivateTmp`, a container without the volumes both
//! mount), never appears — the bridge creates the channel in its own view and would wait in
//! silence. A thread of normal priority, apart from the loop, looks once after a while and
//! says what to check when nothing publishes forces on the channel.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use vademecum_proto::shm::{self, HapticChannel, HapticServices};

/// Where iceoryx2 keeps its files (its default configuration's root path).
pub const ICEORYX2_ROOT: &str = "/tmp/iceoryx2";

/// The watching thread; stopped and joined when dropped.
#[derive(Debug)]
pub struct ServerWatch {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl ServerWatch {
    /// Looks `after` from now whether a server publishes forces on `channel`, and if none
    /// does, prints [`hint`] on stderr (once). Sleeps until then (one wake-up, none on a period).
    pub fn start(channel: &HapticChannel, after: Duration) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let (s, channel) = (stop.clone(), channel.clone());
        let thread = std::thread::Builder::new()
            .name("bridge-watch".into())
            .spawn(move || {
                let deadline = Instant::now() + after;
                while !s.load(Ordering::Relaxed) {
                    let left = deadline.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        if server_publishers(&channel) == Some(0) {
                            eprintln!("{}", hint(&channel, after));
                        }
                        return;
                    }
                    std::thread::park_timeout(left);
                }
            })
            .ok();
        Self { stop, thread }
    }
}

impl Drop for ServerWatch {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

/// Publishers of forces on `channel` (the server's sessions), or `None` if the channel cannot
/// be opened from here.
pub fn server_publishers(channel: &HapticChannel) -> Option<usize> {
    let node = shm::node(&format!("vademecum-bridge-watch-{}", std::process::id())).ok()?;
    let services = HapticServices::open(&node, channel).ok()?;
    Some(services.command.dynamic_config().number_of_publishers())
}

/// What to check when no server appeared on `channel` within `after`.
pub fn hint(channel: &HapticChannel, after: Duration) -> String {
    // SAFETY: plain syscalls with no arguments.
    let (uid, gid) = unsafe { (libc::geteuid(), libc::getegid()) };
    let owner = {
        use std::os::unix::fs::MetadataExt;
        match std::fs::metadata(ICEORYX2_ROOT) {
            Ok(m) if m.uid() != uid => format!(" {ICEORYX2_ROOT} belongs to uid {}, not to this bridge's.", m.uid()),
            Ok(_) => String::new(),
            Err(e) => format!(" {ICEORYX2_ROOT}: {e}."),
        }
    };
    format!(
        "vademecum-bridge: no server has opened channel '{}' after {:.1} s; still waiting.{owner} The server and the bridge meet in iceoryx2's files in {ICEORYX2_ROOT} and /dev/shm: run both on one host as the same user and group (this bridge: uid {uid}, gid {gid}), both seeing the same /tmp and /dev/shm (no systemd PrivateTmp; in Kubernetes, the same memory-backed emptyDir volumes at {ICEORYX2_ROOT} and /dev/shm in both containers), and check the session's haptic channel name.",
        channel.name(),
        after.as_secs_f64()
    )
}
