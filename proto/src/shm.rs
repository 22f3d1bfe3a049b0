//! Shared-memory contracts of the 1 kHz haptic path: the `#[repr(C)]` samples the device
//! bridge and a session's tick thread exchange over iceoryx2, the service names derived from a
//! session's haptic channel, and the one place where both sides open those services with the
//! same quality of service.
//!
//! # Layout
//! - [`HapticState`]: bridge → server, one per bridge tick: the device's tool state.
//! - [`HapticCommand`]: server → bridge, one per state answered: the force to render.
//! - [`BridgeReport`]: bridge → server, a few per second: the bridge's own counters and
//!   latency percentiles, exported by the server's metrics.
//! - [`HapticChannel`]: a validated channel name and the service names under it.
//! - [`HapticServices`]: the services, opened or created with the shared settings (plus two
//!   events a side may block on instead of polling: `wake`, a state was published, and
//!   `answered`, a force was).
//!
//! Times are `CLOCK_MONOTONIC` nanoseconds ([`monotonic_ns`]), one clock for every process
//! on the host, so a latency can be measured across the two processes.
//!
//! Both sides run as the same user: iceoryx2's shared-memory files are created 0600.

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

/// The tool state read from the device at one bridge tick (bridge → server).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("vademecum::HapticState")]
#[repr(C)]
pub struct HapticState {
    /// The bridge's tick number (starts at 0, +1 per tick; a restarted bridge starts again).
    pub seq: u64,
    /// When the device was read (`CLOCK_MONOTONIC`, ns).
    pub t_read_ns: u64,
    /// Tool tip position in the organ frame (m), after the bridge's input guard.
    pub position_m: [f64; 3],
    /// Tool tip velocity (m/s).
    pub velocity_m_s: [f64; 3],
    /// Blade engagement or jaw closure, 0 (open) to 1 (closed).
    pub closure: f64,
    /// Tool kind: [`TOOL_PROBE`], [`TOOL_SCALPEL`] or [`TOOL_GRASPER`].
    pub tool: u32,
    /// [`STATE_ADJUSTED`] when the input guard clamped or held this sample.
    pub flags: u32,
    /// Tool orientation, unit quaternion `[w, x, y, z]`; all zeros: the identity (a device
    /// that does not measure it). For a scalpel the tool frame's y axis turned by it is the
    /// normal of the blade's plane.
    pub orientation: [f64; 4],
    /// A scalpel's blade: the other end of its cutting edge in the organ frame (m);
    /// `position_m` is its tip. Other tools: ignored.
    pub blade_end_m: [f64; 3],
}

/// A spherical-tip probe.
pub const TOOL_PROBE: u32 = 0;
/// A scalpel.
pub const TOOL_SCALPEL: u32 = 1;
/// A grasper.
pub const TOOL_GRASPER: u32 = 2;
/// [`HapticState::flags`]: the device sample was out of range and was clamped or held.
pub const STATE_ADJUSTED: u32 = 1;

/// The force answering one tool state (server → bridge).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("vademecum::HapticCommand")]
#[repr(C)]
pub struct HapticCommand {
    /// The server's answer counter (starts at 1 per session; 0 never appears on the wire).
    pub seq: u64,
    /// [`HapticState::seq`] of the state answered.
    pub state_seq: u64,
    /// [`HapticState::t_read_ns`] of the state answered, echoed (ns).
    pub t_read_ns: u64,
    /// When the server answered (`CLOCK_MONOTONIC`, ns).
    pub t_answer_ns: u64,
    /// Force the tissue exerts on the tool (N): what the device renders.
    pub force_n: [f64; 3],
    /// Penetration depth of the tool into the organ (m); 0 without contact.
    pub depth_m: f64,
    /// The tick's event bits (the engine's `Events`: 1 contact, 2 rejected input, …).
    pub events: u32,
    /// Reserved, 0.
    pub reserved: u32,
    /// How the server waited for the state (`CLOCK_MONOTONIC` ns; 0: not known), so a trace
    /// of the bridge alone can tell where a late answer lost its time: when the server meant
    /// to start polling for the state (the end of its sleep) …
    pub t_peer_planned_ns: u64,
    /// … when it started polling …
    pub t_peer_polling_ns: u64,
    /// … and when it received the state.
    pub t_peer_received_ns: u64,
}

/// The bridge's counters and latency percentiles (bridge → server, a few per second).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("vademecum::BridgeReport")]
#[repr(C)]
pub struct BridgeReport {
    /// When the report was made (`CLOCK_MONOTONIC`, ns).
    pub t_ns: u64,
    /// Bridge ticks run.
    pub ticks: u64,
    /// Ticks whose force was written more than one period after the tick's deadline.
    pub deadline_misses: u64,
    /// Ticks that wrote a force answering a state not seen before (a fresh force).
    pub fresh_forces: u64,
    /// Ticks whose force the watchdog held or faded (no fresh force in time).
    pub watchdog_ticks: u64,
    /// Device samples with a non-finite component (held at the last good state).
    pub rejected_non_finite: u64,
    /// Device samples that moved faster than a hand can (the step was clamped).
    pub clamped_jumps: u64,
    /// Device samples outside the device workspace (clamped to it).
    pub clamped_workspace: u64,
    /// Forces that were non-finite (replaced by zero).
    pub rejected_forces: u64,
    /// Forces longer than the device limit (scaled down).
    pub clamped_forces: u64,
    /// Forces that changed faster than the device's rate limit (slewed).
    pub rate_limited_forces: u64,
    /// Device read → force written, over the fresh forces: percentiles (ns).
    pub latency_p50_ns: u64,
    /// 99th percentile (ns).
    pub latency_p99_ns: u64,
    /// 99.9th percentile (ns).
    pub latency_p999_ns: u64,
    /// Maximum (ns).
    pub latency_max_ns: u64,
}

impl BridgeReport {
    /// The number of its fields, all `u64`.
    pub const WORDS: usize = 15;

    /// Its fields in declaration order: what a reader that keeps the latest report as
    /// atomics, field by field, stores ([`Self::from_words`] reads them back by name).
    pub fn to_words(&self) -> [u64; Self::WORDS] {
        [
            self.t_ns,
            self.ticks,
            self.deadline_misses,
            self.fresh_forces,
            self.watchdog_ticks,
            self.rejected_non_finite,
            self.clamped_jumps,
            self.clamped_workspace,
            self.rejected_forces,
            self.clamped_forces,
            self.rate_limited_forces,
            self.latency_p50_ns,
            self.latency_p99_ns,
            self.latency_p999_ns,
            self.latency_max_ns,
        ]
    }

    /// The report whose fields in declaration order are `words` ([`Self::to_words`]).
    pub fn from_words(words: [u64; Self::WORDS]) -> Self {
        let [
            t_ns,
            ticks,
            deadline_misses,
            fresh_forces,
            watchdog_ticks,
            rejected_non_finite,
            clamped_jumps,
            clamped_workspace,
            rejected_forces,
            clamped_forces,
            rate_limited_forces,
            latency_p50_ns,
            latency_p99_ns,
            latency_p999_ns,
            latency_max_ns,
        ] = words;
        Self {
            t_ns,
            ticks,
            deadline_misses,
            fresh_forces,
            watchdog_ticks,
            rejected_non_finite,
            clamped_jumps,
            clamped_workspace,
            rejected_forces,
            clamped_forces,
            rate_limited_forces,
            latency_p50_ns,
            latency_p99_ns,
            latency_p999_ns,
            latency_max_ns,
        }
    }
}

/// Why a channel name was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelNameError {
    /// The name given.
    pub name: String,
}

impl std::fmt::Display for ChannelNameError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "haptic channel name {:?} is invalid: use 1 to 64 characters among letters, digits, '-', '_' and '.'",
            self.name
        )
    }
}

impl std::error::Error for ChannelNameError {}

/// A haptic channel: the name a session and a bridge agree on (by default the session id),
/// under which its services live:
/// `vademecum/haptic/<name>/{state,command,report,wake,answered}`.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct HapticChannel {
    name: String,
}

impl HapticChannel {
    /// Validates `name`: 1 to 64 characters among ASCII letters, digits, `-`, `_`, `.`.
    pub fn new(name: &str) -> Result<Self, ChannelNameError> {
        let ok = !name.is_empty() && name.len() <= 64 && name.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'));
        if ok {
            Ok(Self { name: name.to_string() })
        } else {
            Err(ChannelNameError { name: name.to_string() })
        }
    }

    /// The channel name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The channel of the scene's tool `tool` in a session on this channel whose scene names
    /// several tools: `<channel>.<tool>` (one bridge per tool: `vademecum-bridge --session
    /// <channel> --tool-name <tool>`). A scene with one tool is driven on the channel itself.
    pub fn for_tool(&self, tool: &str) -> Result<Self, ChannelNameError> {
        Self::new(&format!("{}.{tool}", self.name))
    }

    /// The iceoryx2 service name of one of the channel's services (`state`, `command`,
    /// `report`).
    pub fn service_name(&self, service: &str) -> String {
        format!("vademecum/haptic/{}/{service}", self.name)
    }
}

/// Why the haptic services could not be opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpenError {
    /// The service.
    pub service: String,
    /// iceoryx2's reason.
    pub reason: String,
}

impl std::fmt::Display for OpenError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "cannot open the shared-memory service {}: {} (is another process of a different version or user using this channel?)",
            self.service, self.reason
        )
    }
}

impl std::error::Error for OpenError {}

impl OpenError {
    /// A port of `service` on `channel` could not be created because of `e`; `when_full` says
    /// what a full port table means for the calling side (another bridge, another server).
    pub fn port(channel: &HapticChannel, service: &str, e: impl std::fmt::Debug, when_full: &str) -> Self {
        let e = format!("{e:?}");
        Self {
            service: channel.service_name(service),
            reason: if e.contains("ExceedsMaxSupported") {
                format!("{e}: {when_full}")
            } else {
                e
            },
        }
    }
}

/// The services of a channel, opened (or created, whichever side comes first) with the
/// settings both sides share: one publisher per service, the newest samples kept (a slow
/// reader loses old samples, never blocks a writer), no history for late joiners.
#[derive(Debug)]
pub struct HapticServices {
    /// Tool states, bridge → server.
    pub state: PubSubFactory<ipc::Service, HapticState, ()>,
    /// Forces, server → bridge.
    pub command: PubSubFactory<ipc::Service, HapticCommand, ()>,
    /// Bridge reports, bridge → server.
    pub report: PubSubFactory<ipc::Service, BridgeReport, ()>,
    /// "A state was published", bridge → server: an event for peers that block on it
    /// instead of polling (notifying costs the bridge nothing while nobody listens).
    pub wake: EventFactory<ipc::Service>,
    /// "A force was published", server → bridge: an event for bridges that block on it while
    /// they wait for the answer to their state, instead of polling for it.
    pub answered: EventFactory<ipc::Service>,
}

/// Samples a subscriber keeps before the oldest is overwritten.
pub const SUBSCRIBER_BUFFER: usize = 4;
/// Subscribers per service (the peer plus monitoring tools).
pub const MAX_SUBSCRIBERS: usize = 4;

fn open<T: std::fmt::Debug + ZeroCopySend>(node: &Node<ipc::Service>, name: &str) -> Result<PubSubFactory<ipc::Service, T, ()>, OpenError> {
    let bad = |reason: String| OpenError {
        service: name.to_string(),
        reason,
    };
    let service_name: ServiceName = name.try_into().map_err(|e| bad(format!("{e:?}")))?;
    node.service_builder(&service_name)
        .publish_subscribe::<T>()
        .max_publishers(1)
        .max_subscribers(MAX_SUBSCRIBERS)
        .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
        .history_size(0)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| bad(format!("{e:?}")))
}

fn open_event(node: &Node<ipc::Service>, name: &str) -> Result<EventFactory<ipc::Service>, OpenError> {
    let bad = |reason: String| OpenError {
        service: name.to_string(),
        reason,
    };
    let service_name: ServiceName = name.try_into().map_err(|e| bad(format!("{e:?}")))?;
    node.service_builder(&service_name)
        .event()
        .max_notifiers(MAX_SUBSCRIBERS)
        .max_listeners(MAX_SUBSCRIBERS)
        .open_or_create()
        .map_err(|e| bad(format!("{e:?}")))
}

impl HapticServices {
    /// Opens or creates the channel's services on `node`.
    pub fn open(node: &Node<ipc::Service>, channel: &HapticChannel) -> Result<Self, OpenError> {
        Ok(Self {
            state: open(node, &channel.service_name("state"))?,
            command: open(node, &channel.service_name("command"))?,
            report: open(node, &channel.service_name("report"))?,
            wake: open_event(node, &channel.service_name("wake"))?,
            answered: open_event(node, &channel.service_name("answered"))?,
        })
    }
}

/// The timeout to give iceoryx2's event wait for `left` still to wait: `left` rounded up to
/// whole microseconds. The wait sets the socket's `SO_RCVTIMEO` from a `timeval`, where a
/// timeout under a microsecond becomes zero — which the kernel reads as *wait forever*: a
/// side waiting for a peer that has gone would then never see its deadline.
pub fn event_timeout(left: std::time::Duration) -> std::time::Duration {
    std::time::Duration::from_micros(left.as_nanos().div_ceil(1000) as u64)
}

/// A publisher of `T` on the ipc service.
pub type ShmPublisher<T> = Publisher<ipc::Service, T, ()>;
/// A subscriber of `T` on the ipc service.
pub type ShmSubscriber<T> = Subscriber<ipc::Service, T, ()>;

/// Creates an iceoryx2 node for this process, first removing what crashed processes left
/// behind (their nodes, and their ports in every service), so that a restarted peer can take
/// the single publisher slot of a service again. Signal handling stays with the caller.
pub fn node(name: &str) -> Result<Node<ipc::Service>, OpenError> {
    let bad = |reason: String| OpenError {
        service: format!("node {name}"),
        reason,
    };
    let node_name: NodeName = name.try_into().map_err(|e| bad(format!("{e:?}")))?;
    let node = NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| bad(format!("{e:?}")))?;
    node.try_cleanup_dead_nodes();
    Ok(node)
}

/// Quiets iceoryx2's own console logging to warnings and errors (it logs a harmless notice
/// when no configuration file exists).
pub fn quiet_iceoryx2_logging() {
    set_log_level(LogLevel::Error);
}

/// `CLOCK_MONOTONIC` in nanoseconds: the clock of every timestamp on the haptic path.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bridge_report_goes_through_its_words_field_by_field() {
        let words: [u64; BridgeReport::WORDS] = std::array::from_fn(|i| 1000 + i as u64);
        let r = BridgeReport::from_words(words);
        assert_eq!(r.to_words(), words);
        // declaration order, and every field distinct
        assert_eq!((r.t_ns, r.ticks, r.rate_limited_forces, r.latency_max_ns), (1000, 1001, 1010, 1014));
        assert_eq!(std::mem::size_of::<BridgeReport>(), 8 * BridgeReport::WORDS);
    }

    #[test]
    fn channel_names_are_checked() {
        assert!(HapticChannel::new("lab-1_bench.2").is_ok());
        for bad in ["", "a/b", "white space", &"x".repeat(65)] {
            let e = HapticChannel::new(bad).unwrap_err();
            assert!(e.to_string().contains("haptic channel name"), "{e}");
        }
        assert_eq!(HapticChannel::new("s1").unwrap().service_name("state"), "vademecum/haptic/s1/state");
    }

    #[test]
    fn samples_are_plain_fixed_size_data() {
        // counters and times, position, velocity and closure, tool and flags, orientation, blade end
        assert_eq!(std::mem::size_of::<HapticState>(), 2 * 8 + 7 * 8 + 2 * 4 + 4 * 8 + 3 * 8);
        // counters and times, force and depth, events and reserved, the server's wait times
        assert_eq!(std::mem::size_of::<HapticCommand>(), 4 * 8 + 4 * 8 + 2 * 4 + 3 * 8);
        assert_eq!(std::mem::size_of::<BridgeReport>(), 15 * 8);
    }

    #[test]
    fn the_monotonic_clock_advances() {
        let a = monotonic_ns();
        let b = monotonic_ns();
        assert!(b >= a && a > 0);
    }
}
