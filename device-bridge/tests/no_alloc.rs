//! The bridge loop allocates nothing per tick: a counting allocator counts the allocations of
//! the loop's thread, and a long run makes exactly as many as a short one (everything is
//! sized before the loop starts) over the null link; over shared memory, exactly as many more
//! as iceoryx2 0.10 itself makes per published sample (one small shared state per loan),
//! measured in the same test.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use vademecum_bridge::bridge_loop::{self, BridgeParams};
use vademecum_bridge::device::NullDevice;
use vademecum_bridge::link::{Link, NullLink, ShmLink};
use vademecum_bridge::timing::WaitStrategy;
use vademecum_proto::shm::{self, BridgeReport, HapticChannel, HapticServices};

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts, on the calling thread.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(|c| c.get()) {
            COUNT.with(|n| n.set(n.get() + 1));
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_of_a_run(ticks: u64, link: &mut impl Link) -> u64 {
    let p = BridgeParams {
        strategy: WaitStrategy::Sleep,
        duration: Some(Duration::from_millis(ticks)),
        trace_limit: 10_000,
        report_every: 20,
        ..BridgeParams::default()
    };
    let stop = Arc::new(AtomicBool::new(false));
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    let out = bridge_loop::run(&mut NullDevice::default(), link, &p, &stop).unwrap();
    COUNTING.with(|c| c.set(false));
    assert_eq!(out.report.ticks, ticks);
    COUNT.with(|n| n.get())
}

#[test]
fn the_loop_allocates_nothing_per_tick_over_the_null_link() {
    let short = allocations_of_a_run(20, &mut NullLink::default());
    let long = allocations_of_a_run(300, &mut NullLink::default());
    assert_eq!(short, long, "{short} allocations for 20 ticks, {long} for 300");
}

/// iceoryx2 0.10 itself allocates a small shared state per loaned sample
/// (`ChunkMutSharedState`); measured here on a publisher of the same service.
fn allocations_per_published_sample(ch: &HapticChannel) -> u64 {
    let node = shm::node("noalloc-probe").unwrap();
    let services = HapticServices::open(&node, ch).unwrap();
    let report = services.report.publisher_builder().create().unwrap();
    COUNT.with(|n| n.set(0));
    COUNTING.with(|c| c.set(true));
    for _ in 0..100 {
        let s = report.loan_uninit().unwrap();
        s.write_payload(BridgeReport::default()).send().unwrap();
    }
    COUNTING.with(|c| c.set(false));
    let n = COUNT.with(|n| n.get());
    assert_eq!(n % 100, 0, "{n} allocations for 100 samples");
    n / 100
}

#[test]
fn over_shared_memory_the_loop_allocates_only_what_iceoryx2_does_per_sample() {
    let ch = HapticChannel::new(&format!("noalloc-{}", std::process::id())).unwrap();
    let mut link = ShmLink::open(&ch).unwrap();
    let short = allocations_of_a_run(20, &mut link);
    let long = allocations_of_a_run(300, &mut link);
    drop(link);
    // samples published: one state per tick, a report every 20 ticks and one at the end
    let samples = |ticks: u64| ticks + ticks / 20 + 1;
    let per_sample = allocations_per_published_sample(&HapticChannel::new(&format!("noalloc-probe-{}", std::process::id())).unwrap());
    assert_eq!(
        long - short,
        per_sample * (samples(300) - samples(20)),
        "{short} allocations for 20 ticks, {long} for 300, iceoryx2 makes {per_sample} per sample"
    );
}
