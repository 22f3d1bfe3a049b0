//! Waiting for a deadline at 1 kHz, and the scheduling a real-time loop asks the OS for.
//!
//! A sleeping thread on a shared VM can wake tens of microseconds to a millisecond late;
//! a spinning thread is on time but burns a core. [`WaitStrategy`] names the three ways we
//! wait, and `vademecum bench haptic` measures what each costs (BENCHMARKS.md):
//!
//! - [`WaitStrategy::Sleep`]: `nanosleep` to the deadline. No CPU; the OS's wake-up jitter.
//! - [`WaitStrategy::Spin`]: poll the clock until the deadline. On time; one core at 100 %.
//! - [`WaitStrategy::Hybrid`]: sleep until `window` before the deadline, then spin. About
//!   `window / period` of a core, on time unless the OS wakes the thread later than `window`.
//! - [`WaitStrategy::Event`]: for a session waiting on its bridge only — block on the
//!   iceoryx2 event the bridge raises after each state; the wake-up is a kernel round trip.

use std::time::{Duration, Instant};

/// How a loop waits for its next deadline (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WaitStrategy {
    /// Sleep to the deadline.
    Sleep,
    /// Spin on the clock to the deadline.
    Spin,
    /// Sleep until a window before the deadline, then spin.
    #[default]
    Hybrid,
    /// Block on the iceoryx2 event the bridge raises after each state (a session's wait for
    /// the bridge only; a loop waiting for its own deadline sleeps).
    Event,
}

impl std::str::FromStr for WaitStrategy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "sleep" => Ok(Self::Sleep),
            "spin" => Ok(Self::Spin),
            "hybrid" => Ok(Self::Hybrid),
            "event" => Ok(Self::Event),
            _ => Err(format!("unknown wait strategy {s:?}: use sleep, spin, hybrid or event")),
        }
    }
}

impl std::fmt::Display for WaitStrategy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Sleep => "sleep",
            Self::Spin => "spin",
            Self::Hybrid => "hybrid",
            Self::Event => "event",
        })
    }
}

/// Default spin window of [`WaitStrategy::Hybrid`]: long enough to cover a typical wake-up
/// delay of a sleeping thread on a VM (tens of µs), short enough to cost a fifth of a core
/// at 1 kHz.
pub const DEFAULT_SPIN_WINDOW: Duration = Duration::from_micros(200);

/// Waits until `deadline`, or until `ready()` returns true, whichever comes first; returns
/// whether `ready` fired. `ready` is polled while spinning, and once after a sleep.
pub fn wait_until(deadline: Instant, strategy: WaitStrategy, window: Duration, ready: impl FnMut() -> bool) -> bool {
    let spin_from = match strategy {
        WaitStrategy::Sleep | WaitStrategy::Event => deadline,
        WaitStrategy::Spin => Instant::now(),
        WaitStrategy::Hybrid => deadline.checked_sub(window).unwrap_or(deadline),
    };
    wait_between(spin_from, deadline, ready)
}

/// Sleeps until `spin_from`, then polls `ready` until it returns true or `deadline` passes;
/// returns whether `ready` fired. `ready` is polled at least once.
pub fn wait_between(spin_from: Instant, deadline: Instant, mut ready: impl FnMut() -> bool) -> bool {
    let now = Instant::now();
    if spin_from > now {
        std::thread::sleep(spin_from - now);
    }
    loop {
        if ready() {
            return true;
        }
        if Instant::now() >= deadline {
            return false;
        }
        std::hint::spin_loop();
    }
}

/// Stack a real-time loop touches before it starts ([`prefault_stack`]): far more than a tick
/// uses, so no tick takes a page fault on a stack page seen for the first time.
pub const PREFAULT_STACK: usize = 128 * 1024;

/// Touches [`PREFAULT_STACK`] bytes of the calling thread's stack, so its pages are mapped
/// (and locked, by a later [`lock_memory`]) before the loop needs them.
#[inline(never)]
pub fn prefault_stack() {
    let mut page = [0u8; PREFAULT_STACK];
    std::hint::black_box(&mut page);
}

/// Locks every page the process has mapped now in RAM (`mlockall(MCL_CURRENT)`), so the
/// loop's code, stack and buffers are never paged out and never fault back in (memory the
/// loop allocated before it started included; later allocations are not locked, so a low
/// `RLIMIT_MEMLOCK` cannot make them fail). Refused gracefully: the reason is returned.
pub fn lock_memory() -> Result<(), Refused> {
    // SAFETY: plain syscall with a valid flag.
    if unsafe { libc::mlockall(libc::MCL_CURRENT) } == 0 {
        Ok(())
    } else {
        Err(Refused::denied(Request::LockMemory))
    }
}

/// A held request to the kernel's PM QoS for a CPU wake-up latency bound
/// (`/dev/cpu_dma_latency`), as `cyclictest` holds one: while held, idle CPUs stay in idle
/// states whose exit latency is within the bound — with a bound of 0 they poll rather than
/// halt, so a sleeping real-time thread is not also waiting for a halted (v)CPU to come back.
/// The cost is the idle CPUs' own polling (outside every thread's CPU time, on every core),
/// which is why the bridge holds it only while its loop runs. Released when dropped.
#[derive(Debug)]
pub struct WakeLatencyRequest {
    _file: std::fs::File,
}

/// Asks for CPU wake-ups within `us` microseconds (see [`WakeLatencyRequest`]); refused
/// gracefully (the device needs root, or is missing outside Linux): the reason is returned.
pub fn request_wake_latency(us: u32) -> Result<WakeLatencyRequest, Refused> {
    use std::io::Write;
    let device = |action: &'static str| {
        move |e: std::io::Error| Refused::Device {
            action,
            path: CPU_DMA_LATENCY,
            errno: e.raw_os_error().unwrap_or(libc::EIO),
        }
    };
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .open(CPU_DMA_LATENCY)
        .map_err(device("open"))?;
    // the device takes a native-endian 32-bit value; the request lasts while the file is open
    let bound = i32::try_from(us).unwrap_or(i32::MAX);
    file.write_all(&bound.to_ne_bytes()).map_err(device("write"))?;
    Ok(WakeLatencyRequest { _file: file })
}

/// The kernel's PM QoS device for the CPU wake-up latency ([`WakeLatencyRequest`]).
const CPU_DMA_LATENCY: &str = "/dev/cpu_dma_latency";

/// What a real-time loop asks of the OS ([`Refused::Denied`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// Every mapped page locked in RAM ([`lock_memory`]).
    LockMemory,
    /// `SCHED_FIFO` ([`request_realtime`]).
    Fifo,
    /// The thread pinned to this CPU ([`request_realtime`]).
    Cpu(usize),
}

impl std::fmt::Display for Request {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::LockMemory => f.write_str("mlockall"),
            Self::Fifo => f.write_str("SCHED_FIFO"),
            Self::Cpu(c) => write!(f, "CPU {c}"),
        }
    }
}

/// Why a real-time loop runs without one of its safeguards: never fatal, reported beside its
/// figures (the loop runs, its tail is what the OS left it).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refused {
    /// The caller did not ask for it.
    #[error("not asked")]
    NotAsked,
    /// The thread that asked never said what it was granted (it ended at once, or is not
    /// known).
    #[error("{0}")]
    Unreported(&'static str),
    /// The OS refused the request (e.g. `EPERM` without the capability or the rlimit).
    #[error("{request} refused: {}", std::io::Error::from_raw_os_error(*errno))]
    Denied {
        /// What was asked.
        request: Request,
        /// The OS error number.
        errno: i32,
    },
    /// A device the request goes through could not be opened or written (root only, or
    /// missing outside Linux).
    #[error("cannot {action} {path}: {}", std::io::Error::from_raw_os_error(*errno))]
    Device {
        /// `open` or `write`.
        action: &'static str,
        /// The device.
        path: &'static str,
        /// The OS error number.
        errno: i32,
    },
}

impl Refused {
    /// `request` refused with the calling thread's last OS error.
    fn denied(request: Request) -> Self {
        Self::Denied {
            request,
            errno: std::io::Error::last_os_error().raw_os_error().unwrap_or(libc::EIO),
        }
    }
}

/// Time the hypervisor ran something else while this machine's vCPUs wanted to run (the
/// `steal` column of `/proc/stat`, summed over the CPUs): a thread on a stolen vCPU cannot
/// meet any deadline. `None` where the kernel does not report it.
pub fn vcpu_steal() -> Option<Duration> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    steal_of(&stat)
}

/// The `steal` column of the aggregate `cpu` line of a `/proc/stat` text, in USER_HZ ticks
/// converted to time.
fn steal_of(stat: &str) -> Option<Duration> {
    let line = stat.lines().find(|l| l.starts_with("cpu "))?;
    // user nice system idle iowait irq softirq steal …
    let ticks: u64 = line.split_whitespace().nth(8)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    let hz = u64::try_from(hz).ok().filter(|&h| h > 0)?;
    Some(Duration::from_nanos(ticks.saturating_mul(1_000_000_000 / hz)))
}

/// CPU time consumed by the calling thread so far.
pub fn thread_cpu_time() -> Duration {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is valid and writable; the thread CPU clock exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// CPU time used so far by the whole process (every thread).
pub fn process_cpu_time() -> Duration {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is valid and writable; the process CPU clock exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// What the OS granted a real-time loop.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RealtimeStatus {
    /// `SCHED_FIFO` at this priority, or `None` (normal scheduling) with the reason.
    pub fifo: Result<i32, Refused>,
    /// Pinned to this CPU, or why not (`Ok(None)`: not asked).
    pub cpu: Result<Option<usize>, Refused>,
}

impl std::fmt::Display for RealtimeStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.fifo {
            Ok(p) => write!(f, "SCHED_FIFO priority {p}")?,
            Err(e) => write!(f, "normal scheduling ({e})")?,
        }
        match &self.cpu {
            Ok(Some(c)) => write!(f, ", pinned to CPU {c}"),
            Ok(None) => write!(f, ", not pinned"),
            Err(e) => write!(f, ", not pinned ({e})"),
        }
    }
}

/// Asks for `SCHED_FIFO` at `priority` (when `Some`) and pins the calling thread to `cpu`
/// (when `Some`); whatever the OS refuses is reported, never fatal.
///
/// The policy is the calling thread's alone: it is set with `SCHED_RESET_ON_FORK`, so a thread
/// or process the real-time thread starts later runs with normal scheduling (a library's
/// helper thread spawned from the loop never competes with it at its priority). The threads
/// started before keep theirs.
///
/// Busy-polling under `SCHED_FIFO` trips the kernel's real-time throttle (a ~50 ms stall
/// every second by default), so callers ask for FIFO only with [`WaitStrategy::Sleep`] or
/// [`WaitStrategy::Hybrid`].
pub fn request_realtime(priority: Option<i32>, cpu: Option<usize>) -> RealtimeStatus {
    let fifo = match priority {
        None => Err(Refused::NotAsked),
        Some(p) => {
            let param = libc::sched_param { sched_priority: p };
            // SAFETY: plain syscall on the calling thread with a valid parameter struct.
            let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO | libc::SCHED_RESET_ON_FORK, &param) };
            if rc == 0 { Ok(p) } else { Err(Refused::denied(Request::Fifo)) }
        }
    };
    let cpu = match cpu {
        None => Ok(None),
        Some(c) => {
            // SAFETY: a zeroed cpu_set_t is a valid empty set; CPU_SET bounds-checks `c`.
            let rc = unsafe {
                let mut set: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(c, &mut set);
                libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
            };
            if rc == 0 {
                Ok(Some(c))
            } else {
                Err(Refused::denied(Request::Cpu(c)))
            }
        }
    };
    RealtimeStatus { fifo, cpu }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_strategy_reaches_the_deadline_and_never_returns_early() {
        for s in [WaitStrategy::Sleep, WaitStrategy::Spin, WaitStrategy::Hybrid] {
            let deadline = Instant::now() + Duration::from_micros(300);
            assert!(!wait_until(deadline, s, DEFAULT_SPIN_WINDOW, || false));
            assert!(Instant::now() >= deadline, "{s}");
        }
    }

    #[test]
    fn steal_is_the_eighth_column_of_the_cpu_line() {
        let stat = "cpu  1336869 0 129151 684744 7565 0 1975 21815 0 0\ncpu0 663768 0 62517 352897 1994 0 186 10922 0 0\n";
        // SAFETY: sysconf has no preconditions.
        let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as u64;
        assert_eq!(steal_of(stat), Some(Duration::from_nanos(21815 * (1_000_000_000 / hz))));
        assert_eq!(steal_of("cpu0 1 2 3\n"), None);
        assert_eq!(steal_of("cpu  1 2 3\n"), None);
        assert_eq!(steal_of("cpu  1 2 3 4 5 6 7 x\n"), None);
    }

    #[test]
    fn a_ready_condition_ends_the_wait_while_spinning() {
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut n = 0;
        assert!(wait_until(deadline, WaitStrategy::Spin, DEFAULT_SPIN_WINDOW, || {
            n += 1;
            n == 3
        }));
        assert_eq!(n, 3);
    }

    /// The calling thread's scheduling policy, without the reset-on-fork flag, and the flag.
    fn policy() -> (i32, bool) {
        // SAFETY: plain syscall on the calling thread.
        let p = unsafe { libc::sched_getscheduler(0) };
        (p & !libc::SCHED_RESET_ON_FORK, p & libc::SCHED_RESET_ON_FORK != 0)
    }

    #[test]
    fn only_the_thread_that_asks_runs_under_sched_fifo() {
        // in a thread of its own, which ends with the test
        std::thread::spawn(|| {
            let rt = request_realtime(Some(10), None);
            if let Err(why) = &rt.fifo {
                eprintln!("skipped: SCHED_FIFO is not permitted here ({why})");
                assert_eq!(policy().0, libc::SCHED_OTHER);
                return;
            }
            assert_eq!(policy(), (libc::SCHED_FIFO, true));
            // a thread it starts does not inherit the policy
            let child = std::thread::spawn(policy).join().unwrap();
            assert_eq!(child, (libc::SCHED_OTHER, false));
        })
        .join()
        .unwrap();
    }

    #[test]
    fn strategies_parse_from_their_names() {
        for s in [WaitStrategy::Sleep, WaitStrategy::Spin, WaitStrategy::Hybrid, WaitStrategy::Event] {
            assert_eq!(s.to_string().parse::<WaitStrategy>(), Ok(s));
        }
        assert!("busy".parse::<WaitStrategy>().unwrap_err().contains("sleep, spin, hybrid or event"));
    }
}
