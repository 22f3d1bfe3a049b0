//! `vademecum bench pgd`: the online cost of a vademecum, each figure beside a baseline
//! measured in the same run (these are shared, noisy machines).

use std::hint::black_box;
use std::io::Write;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use serde::Serialize;
use vademecum_engine::bundle::{self, LoadedBundle};
use vademecum_engine::pgd::vademecum::{NodeMajorField, QuantizedField};
use vademecum_engine::pgd::{Footprint, Vademecum};
use vademecum_engine::pipeline::{Effect, Palpation, TickState, ToolInput};

use crate::cli::BenchPgdArgs;

#[derive(Debug, Serialize)]
pub(crate) struct Stat {
    what: String,
    calls: usize,
    pub(crate) p50_us: f64,
    pub(crate) p99_us: f64,
    p999_us: f64,
    max_us: f64,
}

pub(crate) fn stat(what: &str, mut v: Vec<f64>) -> Stat {
    v.sort_by(f64::total_cmp);
    let q = |p: f64| v[((v.len() as f64 - 1.0) * p).round() as usize];
    Stat {
        what: what.into(),
        calls: v.len(),
        p50_us: q(0.5),
        p99_us: q(0.99),
        p999_us: q(0.999),
        max_us: *v.last().unwrap_or(&0.0),
    }
}

/// The engine's deterministic generator, so runs are repeatable.
pub(crate) use vademecum_engine::rng::Rng;

/// Times `n` calls of `f` (µs each), keeping its results alive.
pub(crate) fn time_n(n: usize, mut f: impl FnMut() -> f64) -> Vec<f64> {
    let mut acc = 0.0;
    let v = (0..n)
        .map(|_| {
            let t = Instant::now();
            acc += f();
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    black_box(acc);
    v
}

/// The memory-bound floor: `n` plain reads (an 8-lane f32 sum) of a buffer of `bytes` bytes.
fn streaming_read(bytes: usize, n: usize) -> Vec<f64> {
    let buf: Vec<f32> = (0..bytes / 4).map(|i| i as f32).collect();
    time_n(n, || {
        black_box(&buf)
            .chunks_exact(8)
            .fold([0.0f32; 8], |mut acc, c| {
                for l in 0..8 {
                    acc[l] += c[l];
                }
                acc
            })
            .iter()
            .sum::<f32>() as f64
    })
}

pub fn run(a: BenchPgdArgs) -> anyhow::Result<ExitCode> {
    if a.contacts == 0 || a.fields == 0 {
        bail!("--contacts and --fields must be at least 1");
    }
    let (bundle, loads) = timed_loads(&a.bundle)?;
    let bundle = std::sync::Arc::new(bundle);
    let b = &*bundle;
    let v = &b.vademecum;
    let tris: Vec<[usize; 3]> = b.surface.iter().copied().filter(|t| t.iter().all(|&n| v.is_loadable(n))).collect();
    if tris.is_empty() {
        bail!("the bundle has no surface triangle whose three nodes are loadable");
    }
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    // null loop: the same timing loop, no work
    let mut null = Vec::with_capacity(a.contacts);
    let mut contact = Vec::with_capacity(a.contacts);
    let mut acc = 0.0;
    for _ in 0..a.contacts {
        let t = Instant::now();
        black_box(&mut acc);
        null.push(t.elapsed().as_secs_f64() * 1e6);
    }
    for _ in 0..a.contacts {
        let tri = tris[(rng.next_u64() % tris.len() as u64) as usize];
        let (u, w) = (rng.unit(), rng.unit());
        let (u, w) = if u + w > 1.0 { (1.0 - u, 1.0 - w) } else { (u, w) };
        let bary = [1.0 - u - w, u, w];
        let delta = [0.0, 0.0, -1e-3 * rng.unit()];
        let t = Instant::now();
        let f = match v.contact_compliance(black_box(tri), black_box(bary), Footprint::Tip) {
            Some(c) => Vademecum::contact_force(&c, delta),
            None => [0.0; 3],
        };
        contact.push(t.elapsed().as_secs_f64() * 1e6);
        acc += black_box(f)[2];
    }
    // the whole tick of the palpation effect: move the contact proxy, then the force. First
    // with the proxy reset before every call (a tool appearing at a random point: the search
    // from scratch), then tracking a tool that slides while pressed (the steady state).
    let radius = 0.004;
    let mut palpation = Palpation::new(vec![bundle.clone()], radius, false);
    let n_surface = b.surface.len();
    let (tick, touched, press_points) = press_ticks(&mut palpation, b, &tris, &mut rng, radius, a.contacts, &mut acc);
    // tracking: from one press point to the next in 20 steps, pressed all the way
    let tracking = tracking_ticks(&mut palpation, &press_points, a.contacts, &mut acc);
    // two probes (two hands) tracking pressed slides together, their contacts solved together
    let mut two = Palpation::for_tools(vec![bundle.clone()], vec![radius, radius], &[false]);
    let (two_probes, coupled) = two_probe_ticks(&mut two, &press_points, a.contacts, &mut acc);
    // fields
    let mut coeffs = vec![0.0; v.modes()];
    let mut surface_nodes: Vec<usize> = b.surface.iter().flatten().copied().collect();
    surface_nodes.sort_unstable();
    surface_nodes.dedup();
    let (tf, ts, tr) = field_times(v, &tris, &surface_nodes, &mut coeffs, a.fields, &mut acc);
    let raw = v.f_raw();
    // Node-major surface fields: the bundle's surface in f32 and i16, then synthetic modes of
    // the size of a 30k-node organ's surface for several mode counts (a prefix of the modes is
    // a coarser field), each beside a streaming read of the same bytes.
    let c32: Vec<f32> = coeffs.iter().map(|&c| c as f32).collect();
    let mut out32 = vec![0.0f32; 3 * surface_nodes.len()];
    let nm = NodeMajorField::new(v, &surface_nodes);
    let t32 = time_n(a.fields, || {
        nm.eval(black_box(&c32), &mut out32);
        out32[0] as f64
    });
    let qf = QuantizedField::new(v, &surface_nodes, v.modes());
    let mut scaled = vec![0.0f32; qf.modes()];
    let t16 = time_n(a.fields, || {
        qf.eval(black_box(&c32), &mut scaled, &mut out32);
        out32[0] as f64
    });
    let mut stats_fields = vec![
        stat(
            &format!(
                "surface field, f32 node-major ({} nodes, {:.1} MB)",
                surface_nodes.len(),
                nm.bytes() as f64 / 1e6
            ),
            t32,
        ),
        stat(
            &format!(
                "surface field, i16 node-major ({} nodes, {:.1} MB)",
                surface_nodes.len(),
                qf.bytes() as f64 / 1e6
            ),
            t16,
        ),
    ];
    stats_fields.extend(synthetic_fields(&mut rng, v.modes(), a.surface_nodes, a.fields));
    black_box(acc);
    let mut stats = vec![
        stat("bundle load (verify checksums, build online layout)", loads),
        stat("null timing loop", null),
        stat(
            "contact force (the tip's law in a triangle: nodal stiffnesses interpolated, K delta)",
            contact,
        ),
        stat(
            &format!("probe tick, contact from scratch over {n_surface} surface triangles + force ({touched} touching)"),
            tick,
        ),
        stat("probe tick, proxy tracking a pressed slide + force", tracking),
        stat(
            &format!("two probes' tick, both tracking pressed slides, forces solved together ({coupled} ticks with both in contact)"),
            two_probes,
        ),
        stat(
            &format!("displacement field, whole mesh ({} nodes, f64, mode-major)", v.n_nodes()),
            tf,
        ),
        stat(&format!("displacement field, surface only ({} nodes)", surface_nodes.len()), ts),
        stat(
            &format!("streaming read of the same bytes ({:.1} MB)", (raw.len() * 8) as f64 / 1e6),
            tr,
        ),
    ];
    if let Some(lattice) = &b.anm {
        // the large-deformation law: a random lattice-neighbourhood point, a random depth up to
        // twice the deepest path end
        let deepest = lattice.positions.iter().map(|p| p.d_linear).fold(0.0, f64::max);
        let mut zeta = vec![0.0; lattice.max_modes()];
        let pts: Vec<[f64; 3]> = lattice.positions.iter().map(|p| p.point).collect();
        let t = time_n(a.contacts, || {
            let (i, j) = (
                (rng.next_u64() % pts.len() as u64) as usize,
                (rng.next_u64() % pts.len() as u64) as usize,
            );
            let w = rng.unit();
            let p = [0, 1, 2].map(|k| w * pts[i][k] + (1.0 - w) * pts[j][k]);
            lattice.stiffness_ratio(p, 2.0 * deepest * rng.unit(), 4, &mut zeta).ratio
        });
        stats.push(stat(
            &format!(
                "large deformations: force ratio from the ANM lattice (4 of {} positions, r <= {}, order 6)",
                pts.len(),
                lattice.max_modes()
            ),
            t,
        ));
    }
    stats.extend(stats_fields);
    let mut out = std::io::stdout().lock();
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&stats)?)?;
    } else {
        writeln!(
            out,
            "bundle {}: {} modes, {} nodes, {} load nodes",
            a.bundle.display(),
            v.modes(),
            v.n_nodes(),
            v.load_nodes().len()
        )?;
        write_stats(&mut out, &stats)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Node-major surface fields of synthetic modes, `surface_nodes` nodes (a 30k-node organ's
/// surface) for the bundle's `modes_built` and fewer modes (a prefix of the modes is a coarser
/// field), in f32 and i16, each beside a streaming read of the same bytes; `fields` timings
/// each.
fn synthetic_fields(rng: &mut Rng, modes_built: usize, surface_nodes: usize, fields: usize) -> Vec<Stat> {
    let mut stats = Vec::new();
    let syn_nodes: Vec<usize> = (0..surface_nodes).collect();
    let mut mode_counts = vec![modes_built, 200, 100, 50];
    mode_counts.dedup();
    for modes in mode_counts {
        let syn_f: Vec<f64> = (0..modes * 3 * surface_nodes).map(|_| rng.unit() - 0.5).collect();
        let c: Vec<f32> = (0..modes).map(|_| rng.unit() as f32).collect();
        let mut out = vec![0.0f32; 3 * surface_nodes];
        let f32_field = NodeMajorField::from_mode_major(&syn_f, surface_nodes, modes, &syn_nodes);
        let i16_field = QuantizedField::from_mode_major(&syn_f, surface_nodes, modes, &syn_nodes);
        drop(syn_f);
        let t = time_n(fields, || {
            f32_field.eval(black_box(&c), &mut out);
            out[0] as f64
        });
        stats.push(stat(
            &format!(
                "synthetic surface field, f32 node-major ({} nodes × {modes} modes, {:.1} MB)",
                surface_nodes,
                f32_field.bytes() as f64 / 1e6
            ),
            t,
        ));
        stats.push(stat(
            &format!("streaming read of the same {:.1} MB", f32_field.bytes() as f64 / 1e6),
            streaming_read(f32_field.bytes(), fields),
        ));
        drop(f32_field);
        let mut scaled = vec![0.0f32; modes];
        let t = time_n(fields, || {
            i16_field.eval(black_box(&c), &mut scaled, &mut out);
            out[0] as f64
        });
        stats.push(stat(
            &format!(
                "synthetic surface field, i16 node-major ({} nodes × {modes} modes, {:.1} MB)",
                surface_nodes,
                i16_field.bytes() as f64 / 1e6
            ),
            t,
        ));
        stats.push(stat(
            &format!("streaming read of the same {:.1} MB", i16_field.bytes() as f64 / 1e6),
            streaming_read(i16_field.bytes(), fields),
        ));
    }
    stats
}

/// The bundle at `path`, loaded five times (verifying every checksum, building the online
/// layout), with the time of each load (µs).
fn timed_loads(path: &std::path::Path) -> anyhow::Result<(LoadedBundle, Vec<f64>)> {
    let mut loads = Vec::new();
    let mut bundle = None;
    for _ in 0..5 {
        let t = Instant::now();
        let b = bundle::load_bundle(path).with_context(|| format!("cannot load bundle {}", path.display()))?;
        loads.push(t.elapsed().as_secs_f64() * 1e6);
        bundle = Some(b);
    }
    Ok((bundle.expect("loaded at least once"), loads))
}

/// The displacement field's times, `fields` of each: the whole mesh (f64, mode-major), the
/// surface nodes only, and a streaming read of the bytes the whole-mesh field reads (the
/// baseline); `coeffs` ends with the last evaluation's mode coefficients.
fn field_times(
    v: &Vademecum,
    tris: &[[usize; 3]],
    surface_nodes: &[usize],
    coeffs: &mut [f64],
    fields: usize,
    acc: &mut f64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut full = vec![0.0; 3 * v.n_nodes()];
    let mut surf = vec![0.0; 3 * surface_nodes.len()];
    let (mut tf, mut ts, mut tr) = (Vec::new(), Vec::new(), Vec::new());
    let raw = v.f_raw();
    for i in 0..fields {
        let tri = tris[i % tris.len()];
        v.coefficients(tri, [1.0 / 3.0; 3], [0.0, 0.0, -1.0], coeffs);
        let t = Instant::now();
        v.field(black_box(&*coeffs), &mut full);
        tf.push(t.elapsed().as_secs_f64() * 1e6);
        *acc += black_box(&full)[i % full.len()];
        let t = Instant::now();
        v.field_at(black_box(&*coeffs), surface_nodes, &mut surf);
        ts.push(t.elapsed().as_secs_f64() * 1e6);
        *acc += black_box(&surf)[0];
        // baseline: stream the same bytes as the whole-mesh field reads
        let t = Instant::now();
        let s: f64 = black_box(raw).iter().sum();
        tr.push(t.elapsed().as_secs_f64() * 1e6);
        *acc += black_box(s);
    }
    (tf, ts, tr)
}

/// The palpation's tick times for a tool appearing at random points `radius` minus up to
/// 2 mm off random loadable triangles `tris` of bundle `b`, the proxy reset before each (the
/// search from scratch): the times, how many touched, and the points pressed.
fn press_ticks(
    palpation: &mut Palpation,
    b: &LoadedBundle,
    tris: &[[usize; 3]],
    rng: &mut Rng,
    radius: f64,
    contacts: usize,
    acc: &mut f64,
) -> (Vec<f64>, usize, Vec<[f64; 3]>) {
    let mut tick = Vec::with_capacity(contacts);
    let mut touched = 0usize;
    let mut press_points = Vec::with_capacity(contacts);
    for _ in 0..contacts {
        let tri = tris[(rng.next_u64() % tris.len() as u64) as usize];
        let (u, w) = (rng.unit(), rng.unit());
        let (u, w) = if u + w > 1.0 { (1.0 - u, 1.0 - w) } else { (u, w) };
        let p: Vec<f64> = (0..3)
            .map(|k| (1.0 - u - w) * b.nodes[tri[0]][k] + u * b.nodes[tri[1]][k] + w * b.nodes[tri[2]][k])
            .collect();
        let (e1, e2): (Vec<f64>, Vec<f64>) = (
            (0..3).map(|k| b.nodes[tri[1]][k] - b.nodes[tri[0]][k]).collect(),
            (0..3).map(|k| b.nodes[tri[2]][k] - b.nodes[tri[0]][k]).collect(),
        );
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt().max(f64::MIN_POSITIVE);
        let lift = radius - 0.002 * rng.unit();
        let tip = [p[0] + lift * n[0] / len, p[1] + lift * n[1] / len, p[2] + lift * n[2] / len];
        press_points.push(tip);
        let tool = ToolInput {
            position_m: tip,
            ..ToolInput::default()
        };
        let mut state = TickState::default();
        palpation.reset();
        let t = Instant::now();
        palpation.tick(black_box(&tool), &mut state);
        tick.push(t.elapsed().as_secs_f64() * 1e6);
        if state.force_n != [0.0; 3] {
            touched += 1;
        }
        *acc += black_box(state.force_n)[2];
    }
    (tick, touched, press_points)
}

/// The palpation's tick times while tracking a tool that slides from one of `press_points`
/// to the next in 20 steps, pressed all the way (the steady state): `contacts` of them.
fn tracking_ticks(palpation: &mut Palpation, press_points: &[[f64; 3]], contacts: usize, acc: &mut f64) -> Vec<f64> {
    let mut tracking = Vec::with_capacity(contacts);
    palpation.reset();
    'path: for pair in press_points.windows(2) {
        for i in 0..20 {
            let s = i as f64 / 20.0;
            let tool = ToolInput {
                position_m: [0, 1, 2].map(|k| pair[0][k] + s * (pair[1][k] - pair[0][k])),
                ..ToolInput::default()
            };
            let mut state = TickState::default();
            let t = Instant::now();
            palpation.tick(black_box(&tool), &mut state);
            tracking.push(t.elapsed().as_secs_f64() * 1e6);
            *acc += black_box(state.force_n)[2];
            if tracking.len() == contacts {
                break 'path;
            }
        }
    }
    tracking
}

/// Ticks of two probes at once (`Effect::tick_tools`): one along the press points, the other
/// along them backwards, both pressed; the times, and how many ticks had both in contact.
fn two_probe_ticks(palpation: &mut Palpation, press_points: &[[f64; 3]], contacts: usize, acc: &mut f64) -> (Vec<f64>, usize) {
    let mut times = Vec::with_capacity(contacts);
    let mut both = 0;
    palpation.reset();
    let back: Vec<[f64; 3]> = press_points.iter().rev().copied().collect();
    'path: for (pair, other) in press_points.windows(2).zip(back.windows(2)) {
        for i in 0..20 {
            let s = i as f64 / 20.0;
            let at = |p: &[[f64; 3]]| [0, 1, 2].map(|k| p[0][k] + s * (p[1][k] - p[0][k]));
            let tools = [
                ToolInput {
                    position_m: at(pair),
                    ..ToolInput::default()
                },
                ToolInput {
                    tool: 1,
                    position_m: at(other),
                    ..ToolInput::default()
                },
            ];
            let mut states = [TickState::default(); 2];
            let t = Instant::now();
            palpation.tick_tools(black_box(&tools), &mut states);
            times.push(t.elapsed().as_secs_f64() * 1e6);
            both += usize::from(states.iter().all(|s| s.contact.is_some()));
            *acc += black_box(states[0].force_n)[2] + states[1].force_n[2];
            if times.len() == contacts {
                break 'path;
            }
        }
    }
    (times, both)
}

/// The percentile table of `stats` (Markdown, µs).
pub(crate) fn write_stats(out: &mut impl Write, stats: &[Stat]) -> std::io::Result<()> {
    writeln!(out, "| what | calls | p50 (µs) | p99 (µs) | p99.9 (µs) | max (µs) |")?;
    writeln!(out, "|---|---:|---:|---:|---:|---:|")?;
    for s in stats {
        writeln!(
            out,
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.1} |",
            s.what, s.calls, s.p50_us, s.p99_us, s.p999_us, s.max_us
        )?;
    }
    Ok(())
}
