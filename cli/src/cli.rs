//! Command-line definitions (clap). These are the raw arguments; commands validate them into
//! engine types, and nothing here leaks into the engine.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

const ABOUT: &str = "Real-time soft-tissue simulation for surgical training: offline reduced models, online forces.";

const LONG_ABOUT: &str = "vademecum solves soft-tissue mechanics offline into compact reduced models and serves \
forces and displacements from them in real time.

This build provides static solves of scene files, PGD vademecum builds (bundles), headless \
real-time sessions with recorded forces and frames, mesh inspection, scene validation and \
benchmarks.

Exit status: 0 success; 1 finished but a check failed; 2 error (bad input, solver failure).";

/// The `vademecum` command line.
#[derive(Debug, Parser)]
#[command(name = "vademecum", version, about = ABOUT, long_about = LONG_ABOUT)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Solve a scene's static loads and write the result as .vtu.
    #[command(
        long_about = "Solve a scene's static loads with linear finite elements and write one .vtu per organ \
(displacement, von Mises stress, reactions) plus summary.json.\n\n\
Without SCENE, solves the built-in default scene ('organ'). Open the .vtu files in ParaView \
(Filters > Warp By Vector on 'displacement' shows the deformed shape)."
    )]
    Solve(SolveArgs),
    /// Build the PGD vademecum of every organ of a scene into bundles.
    #[command(
        long_about = "Build the PGD computational vademecum (seed 000, Alg. 2.1) of every organ of a scene: \
the displacement for a unit load in each direction at every accessible surface node, in \
separated form u(x; s) = sum_k F_k(x) G_k(s). K is assembled and factored once; every \
spatial solve reuses the factorization. The stopping criteria come from the scene's \
[fidelity.pgd] section; modes are enriched in blocks (fidelity.pgd.block) and recompressed \
by QR + SVD.\n\n\
One blocked pass over the exact parametric solution (one solve per load state, streamed: \
never held whole) computes the exact contact compliances between neighbouring load nodes \
and measures the error of every prefix of the modes; the bundle keeps the fewest modes that \
meet fidelity.pgd.tolerance (relative L2 over all load states, default 1e-3). Writes one \
bundle folder per organ (manifest.json, scene.toml, .npy arrays, modes in f32).\n\n\
--method snapshots makes the modes from the exact responses instead (the truncated SVD of the \
parametric solution, one solve per load state); those solves shard over machines: `build --shard \
I/N` on each, then `vademecum merge` (the same bundle, to the bit)."
    )]
    Build(BuildArgs),
    /// Merge the shards of a sharded build (`build --shard I/N`) into the bundles.
    #[command(long_about = "Merge the shards of a sharded build into the bundles. Each shard \
(`vademecum build --shard I/N`, on any machine, e.g. a Kubernetes Indexed Job) holds the exact \
responses of its load states; merge checks that every shard is there, solved from the same scene \
text and mesh, covering every load state once, then builds the bundle from them exactly as \
`vademecum build --method snapshots` does in one process (truncated SVD, exact contact \
compliances, the error of every prefix of the modes) — the same bundle to the bit — and removes \
the shards (--keep-shards keeps them).")]
    Merge(MergeArgs),
    /// Run a headless session: a scripted tool trajectory at 1 kHz, forces and frames recorded.
    #[command(long_about = "Run a session with no network client: the tick thread plays a scripted tool \
trajectory at 1 kHz, as a simulator frontend would send it, and the session records every \
tick's force as CSV and displacement frames as .pvd/.vtu (open the .pvd in ParaView and \
warp by 'displacement'), then prints a summary: tick work and lateness percentiles, \
deadline misses, peak force.\n\n\
A headless run is deterministic: the same scene and script give the same recording, bit for \
bit (timing columns aside), on an idle machine or a loaded one. It never falls back to the \
scene's reduced fidelity (fidelity.fallback is for live sessions), the cut thread's and the \
co-rotational deformation's work lands at ticks fixed by the script (the run waits for it \
where a live session would let it land late, so a loaded machine makes the run slower, not \
different), and frame n shows the tick at n / --frame-rate seconds.\n\n\
The vademecum of each organ is taken from <BUNDLES>/<organ>.bundle and built there first \
when it is missing or was built from another scene or mesh. Without --script, the probe \
palpates the middle of the first organ's accessible surface: down 3 mm above it, --depth \
into it over 1 s, hold, slide 15 mm over 2 s, lift (5 s in all); a cutting scene's scalpel \
follows its pre-planned cuts, a tearing scene's grasper closes on its grasp and pulls.\n\n\
Two hands: in a scene that cuts one organ and tears another, the scalpel's incisions and the \
grasper's grasp play at once; --script TOOL=CSV moves the scene's tool of that name (repeat it, \
a tool per script). Every hand moves in the same tick; forces.csv then has a row per hand \
and tick, named in its tool column, and each hand's script is written as \
trajectory_<tool>.csv.\n\n\
Writes <RECORD>/forces.csv (tick, t_s, contact point, force on the tool in N, contact, \
depth, events (the tick's events by name, joined by '|': contact, force_saturated, grasped, tearing, tissue_torn, reduced_fidelity, …), latency_us, force_error_n: the estimated error of the force against the full-order model, empty where the force has no estimate), trajectory.csv, <organ>.pvd + frames/*.vtu and summary.json. \
Exit status 1 when force rows were dropped.")]
    Run(RunArgs),
    /// Serve sessions over gRPC (sessions, interaction stream, viewer frames, health, reflection).
    #[command(long_about = "Serve the vademecum.v1 gRPC API: Sessions (create from a scene and its bundles, \
list, inspect, close), Interaction (bidirectional stream: tool states in, one force response \
each, in order), Viewing (reference geometry, then displacement frames at the viewer's rate, \
30 Hz by default, capped by --max-frame-rate), Info, the standard grpc.health.v1 service and \
server reflection.\n\n\
Prints 'listening on ADDR' once ready. Stops on Ctrl-C: every session is closed and its \
streams end.\n\n\
Authentication: with --tokens-file or VADEMECUM_TOKENS (comma-separated), every call must \
carry 'authorization: Bearer <token>', and a client reaches only the sessions created with \
its token. Without either, --no-auth must be given; an empty token source is an error. With --tls-cert and --tls-key the server speaks TLS (rustls); use it with tokens \
for remote clients. Limits: requests up to 1 MiB (an inline scene), responses up to 64 MiB (the \
geometry of a large organ).")]
    Serve(Box<ServeArgs>),
    /// Ask a running server whether it serves (grpc.health.v1): a probe for container
    /// healthchecks and orchestrators, no shell or other tool needed.
    #[command(long_about = "Ask a running server's standard grpc.health.v1 service (unauthenticated) \
whether it serves, as a container's HEALTHCHECK or an orchestrator's probe would: one Check call, \
with a deadline.\n\n\
Exit status: 0 serving; 1 the server answered but does not serve (NOT_SERVING, or the service \
is unknown); 2 no answer (nothing listening, a timeout, a TLS failure).")]
    Health(HealthArgs),
    /// Drain a running server before it stops: it takes no new session, and this waits for
    /// the sessions it holds to close (a pod's preStop hook; an operator before maintenance).
    #[command(long_about = "Drain a running server before it stops (Fleet.Drain, asked over loopback: \
run it on the server's host, as a Kubernetes preStop hook does): the server places no new session on \
itself from now on — in a fleet its CreateSession goes on placing sessions on its peers — while \
the sessions it holds run on until their clients close them. This command then waits, printing \
what is left, until the server holds no session or --wait seconds have passed.\n\n\
Exit status: 0 the server holds no session; 1 --wait ran out with sessions left (the server \
closes them when it stops); 2 the server could not be asked. --resume ends draining instead.\n\n\
With authentication, give a token with --token, --tokens-file (the server's own file: its first \
token is used), VADEMECUM_TOKEN or VADEMECUM_TOKENS (its first token).")]
    Drain(DrainArgs),
    /// Publish bundles into a content-addressed store, under the digest of their manifest.
    #[command(long_about = "Publish bundles into a content-addressed bundle store: each bundle is \
checked whole (every checksum, as a session loads it), then copied to <STORE>/sha256/<hex>/, where \
<hex> is the SHA-256 of its manifest.json — its digest, printed as sha256:<hex>. The manifest lists \
the SHA-256 of every array and of the scene text, so the digest pins every byte a session reads. \
A session asks for bundles by digest (CreateSession bundle_digests); a server serves them from its \
store (serve --bundle-store), fetching a missing one from its source (serve --bundle-source: the \
store's folder served over HTTP(S), e.g. object storage), and never serves a bundle that hashes \
otherwise. Publishing is atomic (copy, check, rename) and idempotent.")]
    Publish(PublishArgs),
    /// Show what is inside a bundle.
    Inspect(InspectArgs),
    /// Inspect meshes.
    #[command(subcommand)]
    Mesh(MeshCommand),
    /// Print or check scene files.
    #[command(subcommand)]
    Scene(SceneCommand),
    /// What accuracy costs: every fidelity setting of a scene's vademecum, its error and its cost.
    #[command(
        long_about = "Sweep the fidelity settings of a scene's PGD vademecum that trade accuracy for time \
and measure each: one build at --tolerance measures the error of every prefix of the modes against \
the exact parametric solution (relative L2 over all load states); each prefix, with its modes stored \
in f32 or quantised to i16, is a point whose online cost (the surface displacement field of one frame, \
p50 and p99 beside a null loop) and offline cost (bundle bytes, build time) are measured.\n\n\
Then it checks the error estimate every answer carries (ToolResponse.force_error_n) against the full \
model: --estimate-points random contacts of the linear law against the full model's compliance, and, \
for a scene with large deformations, full Newton at --estimate-nodes surface nodes off the lattice \
pushed 1.5 times past its force, and, for a tearing scene, the grasp pulled in six directions that mix \
the load and the two across it against the full-order reference, from virgin tissue and as second \
and third grasps, after another grasp site's pull and after six pulls at two sites; for a cutting \
scene, points between the cracked nodes of its cut (and, with the bare enrichment, of the cut \
halfway) against the full XFEM; for co-rotational cutting, a press of the uncut organ and one \
beside the cut, tick by tick against the deformation's own compliance; for an organ cut and \
deformed largely at once, up to --estimate-nodes surface nodes beside its cut pressed as the lattice \
presses, the composed law against full Newton on the organ cut by split nodes. Exit status 1 when it \
bounds fewer than 95 % of the states.\n\n\
Then, for the effects the scene names: large deformations — the lattice at a quarter, half, one and \
two times fidelity.large.positions blending 1 or 4 positions, and each path's load steps, POD modes \
and ANM order, against full Newton; cutting — local fields or bare enrichment on mode prefixes and \
the sliver rule, the served force against the full XFEM; tearing — POD vectors × vademecum prefixes \
against the full-order reference, and the prefixes build --target-error tries of the whole vademecum \
(its pulls across the load too) by the grasper's force on the calibration's pulls (tear_target.csv); the meshless solver (fidelity.solver = \"meshless\") — support × \
integration and the relaxation's tolerance, against the finite-element Newton solve of the same mesh. \
And the mesh itself: the first organ at --refinements of a procedural mesh's divisions (or the \
scene's file and each --mesh-file), each level's own vademecum, its contact force and strain energy \
against the finest level, with Richardson's order and limit when they converge.\n\n\
Writes <OUT>/study.csv, study.json, error_vs_online.svg and error_vs_bundle.svg (the Pareto front \
marked), estimate.csv and estimate_vs_error.svg, one CSV and plot per sweep (lattice, cut, tear, \
meshless, mesh) and verdict.txt. Resumable: a second run reuses the build (same scene and tolerance), \
the points already measured, the estimate's check and every sweep done (the meshless solves one by \
one).\n\n\
The contact force comes from exact local compliances and has no mode error. Default OUT: \
out/<scene name>/study."
    )]
    Study(StudyArgs),
    /// Run the numerical self-checks (the hard-case suite).
    #[command(subcommand)]
    Check(CheckCommand),
    /// Measure solver performance.
    #[command(subcommand)]
    Bench(BenchCommand),
}

/// Arguments of `vademecum health`.
#[derive(Debug, Args)]
pub struct HealthArgs {
    /// The server: `http://HOST:PORT`, or `https://HOST:PORT` for a server with --tls-cert.
    #[arg(long, default_value = "http://127.0.0.1:50051", value_name = "URL")]
    pub addr: String,
    /// The service to ask about (e.g. `vademecum.v1.Sessions`); empty: the whole server.
    #[arg(long, default_value = "")]
    pub service: String,
    /// Give up after this many seconds (connecting included).
    #[arg(long, default_value_t = 3.0, value_name = "S")]
    pub timeout: f64,
    /// CA certificate (PEM) to trust for an https:// server (its own certificate when
    /// self-signed). Default: the platform's roots.
    #[arg(long, value_name = "PEM")]
    pub ca: Option<std::path::PathBuf>,
}

/// Arguments of `vademecum publish`.
#[derive(Debug, Args)]
pub struct PublishArgs {
    /// Bundle folders (`<organ>.bundle`), or folders holding them (every `*.bundle` inside).
    #[arg(required = true)]
    pub bundles: Vec<PathBuf>,
    /// The store.
    #[arg(long, value_name = "DIR")]
    pub store: PathBuf,
    /// Print `{"organ": "sha256:…"}` as JSON (what CreateSession's bundle_digests takes).
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum drain`.
#[derive(Debug, Args)]
pub struct DrainArgs {
    /// The server, on this host: `http://127.0.0.1:PORT` (or `https://` with --ca).
    #[arg(long, default_value = "http://127.0.0.1:50051", value_name = "URL")]
    pub addr: String,
    /// Wait at most this many seconds for the sessions to close (0: do not wait).
    #[arg(long, default_value_t = 3600.0, value_name = "S")]
    pub wait: f64,
    /// End draining: the server takes new sessions again.
    #[arg(long)]
    pub resume: bool,
    /// Bearer token (default: the first of --tokens-file, else VADEMECUM_TOKEN, else the first
    /// of VADEMECUM_TOKENS).
    #[arg(long, value_name = "TOKEN", conflicts_with = "tokens_file")]
    pub token: Option<String>,
    /// The server's token file (one token per line, '#' comments): its first token is used.
    #[arg(long, value_name = "FILE")]
    pub tokens_file: Option<std::path::PathBuf>,
    /// CA certificate (PEM) to trust for an https:// server.
    #[arg(long, value_name = "PEM")]
    pub ca: Option<std::path::PathBuf>,
}

/// Arguments of `vademecum study`.
#[derive(Debug, Args)]
pub struct StudyArgs {
    /// The scene (its first organ is studied).
    #[command(flatten)]
    pub source: SceneSource,
    /// Output folder (kept between runs: the study resumes). Default: `out/<scene name>/study`.
    #[arg(long, short, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// The tolerance of the study's build: the tightest point of the sweep.
    #[arg(long, default_value_t = 1e-4, value_name = "E")]
    pub tolerance: f64,
    /// Frames timed per point.
    #[arg(long, default_value_t = 2000, value_name = "N")]
    pub frames: usize,
    /// Contact states of the linear law sampled to check the per-answer error estimate
    /// against the full model (3 solves each).
    #[arg(long, default_value_t = 40, value_name = "N")]
    pub estimate_points: usize,
    /// Surface nodes off the lattice where full Newton checks the large-deformation error
    /// estimate (one Newton path each, pushed 1.5× past the lattice's force).
    #[arg(long, default_value_t = 12, value_name = "N")]
    pub estimate_nodes: usize,
    /// The mesh sweep's levels, as factors of a procedural mesh's divisions (give 1 alone to
    /// skip the sweep). Each level builds its own vademecum.
    #[arg(long, value_delimiter = ',', default_values_t = [0.5, 1.0, 1.5], value_name = "F,F,...")]
    pub refinements: Vec<f64>,
    /// A coarser or finer mesh of the first organ (same units and `scale` as the scene's file),
    /// a level of the mesh sweep beside the scene's own (repeat for more). For scenes whose
    /// mesh is a file.
    #[arg(long, value_name = "FILE")]
    pub mesh_file: Vec<PathBuf>,
}

/// `vademecum check …`.
#[derive(Debug, Subcommand)]
pub enum CheckCommand {
    /// Drive every method through its numerically hard cases and print the verdicts.
    #[command(long_about = "Drive every method through the inputs where numerical methods break and print one \
row per case: the case, the method, what it must produce, what it produced, its error against \
the case's reference, its time, and the verdict.\n\n\
Cases: near-incompressibility (ν = 0.4999 and 0.5) per element and locking option; every \
hyperelastic law stretched 100 % and compressed 50 % against the exact homogeneous answer; \
element inversion and St Venant-Kirchhoff crushing (Newton's diagnostic); the ANM series past its \
validity radius and past the limit point; the large-deformation lattice far from its positions \
and past its paths; the meshless solver with a cut through nodes, a piece cut loose, ν = 0.499 \
and 100 % stretch; the tick under NaN/Inf in every tool-state field, a 10 cm jump in one tick, \
limits at and past their edge, contact outside the accessible region; XFEM cuts through nodes, \
at ν = 0.499 and cutting a piece loose, malformed blades; tearing to full damage, at ν = 0.499 \
and outside the vademecum's box.\n\n\
A case passes with a finite, bounded answer within its error, or the typed diagnostic it names \
(never NaN, a panic or a silent wrong answer). Exit status 1 when any case fails. The verdicts \
at full size are in docs/stability.md; `cargo test` runs the suite with --reduced.")]
    HardCases(HardCasesArgs),
}

/// Arguments of `vademecum check hard-cases`.
#[derive(Debug, Args)]
pub struct HardCasesArgs {
    /// Smaller problems (the suite in tens of seconds; what `cargo test` runs).
    #[arg(long)]
    pub reduced: bool,
    /// Only the cases whose name or method contains this text (case-insensitive).
    #[arg(long, value_name = "TEXT")]
    pub only: Option<String>,
    /// Also write the verdicts as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Print the table as Markdown (for docs/stability.md) instead of aligned text.
    #[arg(long)]
    pub markdown: bool,
}

/// The built-in scenes' names, from the scenes compiled into the binary (`--help` lists them
/// and a name not among them is refused with the list).
fn builtin_names() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(vademecum_engine::scene::BUILTIN_NAMES)
}

/// Which scene a command works on: a file, or a built-in scene.
#[derive(Debug, Args)]
pub struct SceneSource {
    /// Scene file (TOML). Default: the built-in scene named by --builtin.
    pub scene: Option<PathBuf>,
    /// Built-in scene to use when no SCENE is given (`vademecum scene show NAME` prints one).
    #[arg(long, default_value = "organ", conflicts_with = "scene", value_parser = builtin_names())]
    pub builtin: String,
}

/// Arguments of `vademecum solve`.
#[derive(Debug, Args)]
pub struct SolveArgs {
    /// The scene.
    #[command(flatten)]
    pub source: SceneSource,
    /// Output folder. Default: `out/<scene name>`.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Print a machine-readable JSON summary on stdout instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// Refuse, before assembling, an organ whose direct solve is estimated to need more than
    /// this many GB. Default: the memory the system has available.
    #[arg(long, value_name = "GB")]
    pub max_memory: Option<f64>,
}

/// Arguments of `vademecum build`.
#[derive(Debug, Args)]
pub struct BuildArgs {
    /// The scene.
    #[command(flatten)]
    pub source: SceneSource,
    /// Output folder; each organ's bundle goes to `<OUT>/<organ>.bundle`. Default: `out/<scene name>`.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Keep the greedy modes as they are instead of recompressing them (QR + SVD).
    #[arg(long)]
    pub no_recompress: bool,
    /// Refuse, before assembling, an organ whose direct solve is estimated to need more than
    /// this many GB. Default: the memory the system has available.
    #[arg(long, value_name = "GB")]
    pub max_memory: Option<f64>,
    /// Keep the fewest modes whose measured error (relative L2 over all load states) meets E,
    /// instead of the scene's fidelity.pgd.tolerance; on a tearing scene also the fewest
    /// tearing PGD modes (5, 10, 20, … per pull pattern) whose grasper's force, calibrated
    /// against the full-order model on nine pulls (from virgin tissue and as second grasps), is
    /// within E (relative) at the last load; on a
    /// large-deformation scene also the fewest lattice positions (2, 4, 8, … up to twice
    /// fidelity.large.positions, in farthest-point order) whose served force is within E
    /// (relative) of full Newton at 12 surface nodes off the lattice, at every depth within
    /// the lattice's force; on a cutting scene with local fields also the largest sliver rule
    /// (5e-2, 1e-2, 1e-3, else the scene's) whose force on the scene's cut is within E of the
    /// full XFEM's (never refused: the scene's rule is exact).
    /// Refuse (exit 1, no bundle written) with the closest achievable error when no setting
    /// meets it. `vademecum study` shows the whole trade-off.
    #[arg(long, value_name = "E")]
    pub target_error: Option<f64>,
    /// Also require the online cost that depends on the modes — the surface displacement
    /// field of one frame, timed here on 64 real contacts (p50) — to be at most T µs: keep the
    /// fewest modes meeting the error target (E, or the scene's tolerance) if they do; refuse
    /// (exit 1, no bundle written) saying how many modes and what error fit within T when they
    /// do not. The haptic force costs the same at every number of modes (exact local
    /// compliances). On a tearing scene also a step of each grasp site's kept modes; on a
    /// cutting scene also the compliance the scene's cut adds at a contact (at the kept sliver
    /// rule, from the contact table a session keeps).
    #[arg(long, value_name = "T")]
    pub target_tick_us: Option<f64>,
    /// Print the build report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Where the modes come from: `pgd`, the greedy PGD (seed 000, Alg. 2.1; sequential: each mode
    /// corrects the ones before it), or `snapshots`, the truncated SVD of the exact response
    /// of every load state (one solve each with the factorization, then QR + SVD: the best
    /// basis of each size; its solves shard over machines with --shard).
    #[arg(long, value_enum, default_value_t = ModesMethod::Pgd)]
    pub method: ModesMethod,
    /// Solve only shard I of N (0-based, I = 0..N-1, as Kubernetes' JOB_COMPLETION_INDEX) of
    /// the exact responses of every organ's load states, into `<OUT>/<organ>.shard-I-of-N`;
    /// `vademecum merge` then writes the bundles — the same, to the bit, as `--method
    /// snapshots` in one process. Implies --method snapshots. Linear palpation scenes only
    /// (a scene with large deformations, cutting or tearing builds in one process).
    #[arg(long, value_name = "I/N", conflicts_with_all = ["target_error", "target_tick_us"])]
    pub shard: Option<vademecum_engine::offline::shard::ShardOf>,
}

/// [`BuildArgs::method`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModesMethod {
    /// The greedy PGD.
    Pgd,
    /// The truncated SVD of the exact responses.
    Snapshots,
}

/// Arguments of `vademecum merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The scene the shards were solved for.
    #[command(flatten)]
    pub source: SceneSource,
    /// The folder the shards were written to (`build --shard … --out`); the bundles go there
    /// too. Default: `out/<scene name>`.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Wait up to S seconds for every shard to be complete (a merge started beside the shards,
    /// as a Kubernetes Job beside an Indexed Job).
    #[arg(long, default_value_t = 0.0, value_name = "S")]
    pub wait: f64,
    /// Keep the shard folders once the bundles are written (default: removed).
    #[arg(long)]
    pub keep_shards: bool,
    /// Also publish the bundles into this content-addressed store (see `vademecum publish`)
    /// and print their digests.
    #[arg(long, value_name = "STORE")]
    pub publish: Option<PathBuf>,
    /// Keep the fewest modes whose measured error meets E instead of fidelity.pgd.tolerance;
    /// refuse (exit 1, no bundle written) when none does.
    #[arg(long, value_name = "E")]
    pub target_error: Option<f64>,
    /// Refuse, before assembling, an organ whose direct solve is estimated to need more than
    /// this many GB. Default: the memory the system has available.
    #[arg(long, value_name = "GB")]
    pub max_memory: Option<f64>,
    /// Print the build report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The scene.
    #[command(flatten)]
    pub source: SceneSource,
    /// Tool trajectory as CSV keyframes `t_s,x_m,y_m,z_m[,closure]` (SI units, times
    /// increasing), interpolated linearly at every tick. `TOOL=CSV` moves the scene's tool of
    /// that name; repeat it for several hands at once (each names its tool). Default: the
    /// built-in palpation, incisions or grasp — both hands at once in a scene that cuts and
    /// tears.
    #[arg(long, value_name = "[TOOL=]CSV")]
    pub script: Vec<String>,
    /// Folder for forces.csv, frames and summary.json. Default: `out/<scene name>/run`.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// Folder of the bundles (`<organ>.bundle`), built there when missing or stale.
    /// Default: `out/<scene name>`.
    #[arg(long, value_name = "DIR")]
    pub bundles: Option<PathBuf>,
    /// Frames recorded per second (at most 60).
    #[arg(long, default_value_t = 30.0, value_name = "HZ")]
    pub frame_rate: f64,
    /// How deep the built-in palpation presses (m). Default: 4 mm, or less on a
    /// large-deformation scene: 90 % of the depth where the lattice's paths around the slide
    /// end, so that every answer comes from them (deeper, the law is extrapolated and the
    /// answers' error estimates grow: docs/accuracy.md).
    #[arg(long, value_name = "M")]
    pub depth: Option<f64>,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Drive the session from a device bridge instead of the script: open this haptic
    /// channel (shared memory) and answer `vademecum-bridge --session CHANNEL` until
    /// --duration or Ctrl-C. The built-in palpation is still written as
    /// `<record>/trajectory.csv`, a hand script for `vademecum-bridge --device sim`.
    #[arg(long, value_name = "CHANNEL")]
    pub haptic: Option<String>,
    /// With --haptic: stop after this many seconds (default: at Ctrl-C or SIGTERM).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// With --haptic: how the tick thread waits for the bridge's states: `hybrid` (sleep,
    /// then poll the last --haptic-spin-us before a state is due; default), `spin` (poll
    /// continuously: a whole core), `event` (block on the event the bridge raises after
    /// each state: no spinning, a kernel wake-up per answer), `sleep` (answer at the
    /// session's own 1 kHz ticks: no spinning, forces one tick late).
    #[arg(long, value_name = "WAIT")]
    pub haptic_wait: Option<vademecum_bridge::timing::WaitStrategy>,
    /// With --haptic: spin window of the hybrid wait (µs).
    #[arg(long, default_value_t = 200, value_name = "US")]
    pub haptic_spin_us: u64,
}

/// Arguments of `vademecum serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Address to listen on (port 0: any free port, printed at start).
    #[arg(long, default_value = "127.0.0.1:50051", value_name = "ADDR")]
    pub listen: String,
    /// Also serve the browser viewer on this address (http://ADDR/: the sessions, the organ
    /// deforming, the tool and its force) and gRPC-web for it and for other web frontends
    /// (Sessions, Viewing, Info; HTTP/1.1; the same tokens). Pages from other origins may
    /// call it when the server has tokens; without tokens only those --web-origin names.
    #[arg(long, value_name = "ADDR")]
    pub web: Option<String>,
    /// An origin (`https://host[:port]`) whose pages may call the web port's gRPC-web
    /// (repeatable). Default: any origin with tokens, none but the viewer's own with
    /// --no-auth (never every origin without tokens).
    #[arg(long, value_name = "ORIGIN", requires = "web")]
    pub web_origin: Vec<String>,
    /// Also serve Prometheus metrics (GET /metrics, unauthenticated) on this address; loopback
    /// only unless --metrics-public.
    #[arg(long, value_name = "ADDR")]
    pub metrics: Option<String>,
    /// Folder that scene paths sent by clients resolve under (and inline scenes' mesh paths).
    #[arg(long, default_value = ".", value_name = "DIR")]
    pub scene_root: PathBuf,
    /// Folder every mesh file named by a client's scene must lie in (after resolving '..' and
    /// symbolic links); others are refused with PERMISSION_DENIED. Default: the scene root.
    #[arg(long, value_name = "DIR")]
    pub mesh_root: Option<PathBuf>,
    /// Folder that bundle folders named by clients resolve under.
    #[arg(long, default_value = ".", value_name = "DIR")]
    pub bundle_root: PathBuf,
    /// Refuse server-side scene paths (clients must send the scene text).
    #[arg(long)]
    pub no_paths: bool,
    /// Most sessions at once.
    #[arg(long, default_value_t = 16)]
    pub max_sessions: usize,
    /// Most cells of a built-in mesh in a client's scene (counted before it is made;
    /// RESOURCE_EXHAUSTED beyond).
    #[arg(long, default_value_t = 2_000_000, value_name = "CELLS")]
    pub max_scene_cells: usize,
    /// Most CreateSessions prepared at once (scene, meshes, bundles); RESOURCE_EXHAUSTED
    /// beyond (the client retries).
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub max_preparing: usize,
    /// Most sessions one client (bearer token) holds at once (with authentication).
    #[arg(long, default_value_t = 4)]
    pub client_sessions: usize,
    /// Most interaction streams, and most viewer streams, open at once.
    #[arg(long, default_value_t = 256)]
    pub max_streams: u32,
    /// Most interaction streams, and most viewer streams, one client holds open (with
    /// authentication).
    #[arg(long, default_value_t = 16)]
    pub client_streams: u32,
    /// Highest frame rate a viewer gets (Hz).
    #[arg(long, default_value_t = 60.0, value_name = "HZ")]
    pub max_frame_rate: f64,
    /// File with one accepted bearer token per line ('#' comments); enables authentication.
    #[arg(long, value_name = "FILE", conflicts_with = "no_auth")]
    pub tokens_file: Option<PathBuf>,
    /// Serve without authentication (every client is 'anonymous' and sees every session).
    /// Required when no token source is given: the server never runs open by accident.
    #[arg(long)]
    pub no_auth: bool,
    /// Allow --metrics on an address that is not loopback (the metrics page is not
    /// authenticated: it shows session labels, counts and latencies).
    #[arg(long)]
    pub metrics_public: bool,
    /// TLS certificate chain (PEM); with --tls-key, serves TLS (rustls) for remote clients.
    #[arg(long, value_name = "PEM", requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// TLS private key (PEM).
    #[arg(long, value_name = "PEM", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// Tick workers: threads that each tick many sessions, answering tool states on arrival
    /// (default: one per CPU this process may use; 0: a thread per session). A session with a
    /// device bridge ticks on a device worker (--device-workers) or a thread of its own.
    #[arg(long, value_name = "N")]
    pub tick_workers: Option<usize>,
    /// Device workers: threads that each tick many sessions driven by device bridges, blocked
    /// on all their bridges' events at once (the event wait: implies --haptic-wait event) —
    /// for many devices on one host. Default 0: a thread per device session, which lets
    /// one device use the lower-latency hybrid wait.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub device_workers: usize,
    /// Hold a PM QoS request for CPU wake-ups within US microseconds while serving
    /// (`/dev/cpu_dma_latency`, as `cyclictest` and the bridge hold one; needs root): idle CPUs
    /// stay in shallow idle states (0: they poll), so a worker woken by a tool state or an
    /// answer does not also wait for a halted CPU to come back. Its price is the idle CPUs'
    /// polling on every core, which no thread's CPU figure includes. Refused gracefully
    /// (said at start).
    #[arg(long, value_name = "US")]
    pub wake_latency_us: Option<u32>,
    /// Pin tick worker k to CPU k.
    #[arg(long)]
    pub pin_tick_workers: bool,
    /// Never fall back to a cheaper setting under load, whatever the scenes say (by default a
    /// session whose ticks come close to their deadline runs its scene's reduced fidelity
    /// until the load falls: `fidelity.fallback` in docs/scene-format.md).
    #[arg(long)]
    pub no_fidelity_fallback: bool,
    /// Ask SCHED_FIFO at this priority (1-99) for the tick workers; refused gracefully (and
    /// logged) when the OS does not permit it.
    #[arg(long, value_name = "PRIORITY", value_parser = clap::value_parser!(i32).range(1..=99))]
    pub tick_fifo: Option<i32>,
    /// Admission control: refuse a new session (RESOURCE_EXHAUSTED, saying the load) when it
    /// would take the least-loaded tick worker's measured utilisation above this fraction.
    #[arg(long, default_value_t = 0.6, value_name = "FRACTION")]
    pub max_tick_load: f64,
    /// Frame workers: threads that each make the 30 Hz frames of many sessions (default: one
    /// per CPU this process may use; 0: a thread per session). A co-rotational cutting session
    /// makes its frames on a thread of its own.
    #[arg(long, value_name = "N")]
    pub frame_workers: Option<usize>,
    /// How the tick thread of a session driven by a device bridge waits for the bridge's
    /// states: `hybrid` (sleep, then poll the last 200 µs before a state is due; default: the
    /// lowest latency, a fifth of a core per session), `event` (block on the event the bridge
    /// raises after each state: no spinning — for many device sessions on one host), `spin`,
    /// `sleep` (see `vademecum run --haptic-wait`).
    #[arg(long, value_name = "WAIT")]
    pub haptic_wait: Option<vademecum_bridge::timing::WaitStrategy>,
    /// This server's name (1 to 40 of A-Z a-z 0-9 . _ -): in a fleet its session ids start with
    /// it. Default: the host name (a pod's name).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// Another server of this server's fleet, as this server reaches it (repeat for each; also
    /// VADEMECUM_PEERS, comma-separated). With peers, every CreateSession here places the
    /// session on the least-loaded server of the fleet and answers with a redirect to it
    /// (proto/vademecum/v1/fleet.proto, deploy/k8s/). Every server of a fleet must accept the
    /// same tokens.
    #[arg(long = "peer", value_name = "URL", requires = "advertise")]
    pub peers: Vec<String>,
    /// This server's address as clients reach it (put in redirects to it), e.g.
    /// `http://vademecum-0.vademecum.NAMESPACE.svc.cluster.local:50051`.
    #[arg(long, value_name = "URL")]
    pub advertise: Option<String>,
    /// CA certificate (PEM) that https:// peers' certificates are checked against.
    #[arg(long, value_name = "PEM")]
    pub peer_ca: Option<PathBuf>,
    /// Content-addressed bundle store (`vademecum publish --store`): sessions asking for bundles
    /// by digest (CreateSession bundle_digests) are served from it, and only with bundles that
    /// hash to what they asked.
    #[arg(long, value_name = "DIR")]
    pub bundle_store: Option<PathBuf>,
    /// Fetch a bundle missing from --bundle-store from here: an http(s):// base URL serving a
    /// published store's folders (`<URL>/sha256/<hex>/manifest.json`, …), e.g. an object
    /// storage bucket. Every fetched file is checked against the digest before use.
    #[arg(long, value_name = "URL", requires = "bundle_store")]
    pub bundle_source: Option<String>,
    /// Give up a fetch from --bundle-source after this long, its every request included (a
    /// source that hangs holds the CreateSession that asked no longer; the session is refused
    /// with FAILED_PRECONDITION).
    #[arg(long, value_name = "SECONDS", default_value_t = 120.0, requires = "bundle_source")]
    pub bundle_fetch_timeout: f64,
    /// Most bytes one bundle fetched from --bundle-source may hold, its files together
    /// (checked against what its manifest declares before an array is read).
    #[arg(long, value_name = "MIB", default_value_t = 2048, requires = "bundle_source")]
    pub bundle_fetch_max_mib: u64,
    /// Run as an Agones GameServer (deploy/k8s/, agones.enabled): Ready once serving, health
    /// pings, the Counter "sessions" kept at the sessions held, Allocated while it holds any
    /// (a fleet scale-down or rolling update never removes it), Shutdown once drained. Needs
    /// the Agones SDK sidecar (localhost:AGONES_SDK_GRPC_PORT, 9357 by default; waits 30 s
    /// for it).
    #[arg(long)]
    pub agones: bool,
}

/// Arguments of `vademecum inspect`.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// Bundle folder (written by `vademecum build`).
    pub bundle: PathBuf,
    /// Print the manifest as JSON.
    #[arg(long)]
    pub json: bool,
}

/// `vademecum mesh …`.
#[derive(Debug, Subcommand)]
pub enum MeshCommand {
    /// Print node and cell counts, volumes, aspect ratios and inverted cells of a mesh file.
    Info(MeshInfoArgs),
}

/// Arguments of `vademecum mesh info`.
#[derive(Debug, Args)]
pub struct MeshInfoArgs {
    /// Mesh file: Gmsh .msh (v1, v2, v4.1; ASCII or binary) or VTK (.vtu, legacy .vtk).
    pub file: PathBuf,
    /// Multiply coordinates by this factor first (e.g. 0.001 for a mesh in mm).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `vademecum scene …`.
#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// Print a built-in scene's TOML (a starting point for your own).
    Show {
        /// Built-in scene name.
        #[arg(default_value = "organ", value_parser = builtin_names())]
        name: String,
    },
    /// Validate a scene file and the meshes it names, without solving.
    Check {
        /// The scene file.
        file: PathBuf,
    },
}

/// `vademecum bench …`.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Assembly, factorization and solve time on the built-in block.
    #[command(long_about = "Assembly, symbolic analysis, Cholesky factorization and solve time of the static \
linear problem on the built-in block (clamped at one end, tip load), at the requested sizes.\n\n\
Sizes are approximate: the block is a 4:1:1 bar of cubes whose node count gives about the \
requested number of degrees of freedom.")]
    Fe(BenchFeArgs),
    /// Online cost of a vademecum bundle: load time, contact force per tick, displacement fields.
    #[command(
        long_about = "Online cost of a vademecum bundle, each figure beside a baseline measured in the same run: \
bundle load time; contact-force evaluation (compliance at a random point of a random \
accessible surface triangle, then f = C^-1 delta) per call, beside a null loop that only \
reads the clock; the displacement field of the whole mesh and of the surface nodes only, \
beside a plain streaming read of the same bytes. Percentiles are of individual calls."
    )]
    Pgd(BenchPgdArgs),
    /// Real-time behaviour of sessions: tick latency with and without viewers, gRPC round
    /// trip at 1 kHz, concurrent sessions — each beside a null loop.
    #[command(
        long_about = "Real-time behaviour of sessions on the built-in organ, each figure beside a null loop \
measured in the same run (a thread sleeping to the same 1 ms deadlines, doing nothing): \
a session's tick work and lateness with no viewer and with three (2 x 30 Hz, 5 Hz); the \
gRPC round trip on loopback with one tool state per millisecond, beside tonic's echo of the \
same stream; deadline misses of N concurrent sessions each playing the built-in palpation, \
with a thread each and on the tick workers (one per CPU).\n\n\
To measure what one core sustains, pin the process: taskset -c 0 vademecum bench session."
    )]
    Session(BenchSessionArgs),
    /// A server under many sessions over real gRPC: tick misses beside a null loop, round trips
    /// beside tonic's echo, CPU and RSS.
    #[command(
        long_about = "Starts `vademecum serve` (this executable) on a free loopback port, creates --sessions \
sessions of the built-in organ and drives each, for --seconds, with --clients-per-session interaction \
streams sending tool states at --rate (each after the previous answer, as a frontend does) and \
--viewers viewers at 30 Hz. Reported from the same run: the sessions' deadline misses beside a null \
loop in this process (a thread sleeping to 1 ms deadlines), every client's round trip beside a tonic \
echo of the same stream and pacing, every tool state accounted for (sent = answered + refused + in flight when a killed client died + \
lost), the server's CPU and RSS, and what each session reports it holds in memory. Every --window \
seconds it samples the RSS and the misses (a soak's time series). --chaos-every S kills a random \
client with SIGKILL every S seconds (the clients of --chaos-clients sessions run as processes of \
their own) and restarts it. --haptic K drives K of the sessions with device bridges \
(vademecum-bridge, a simulated stylus over shared memory) instead of gRPC clients. Prints a \
table; --json FILE writes the figures.\n\n\
Examples:\n  vademecum bench load --sessions 32 --seconds 30 --json out/load.json\n  \
vademecum bench load --seconds 600 --window 30 --chaos-every 5     # a soak with chaos\n  \
vademecum bench load --sessions 16 --haptic 4                      # with device sessions"
    )]
    Load(BenchLoadArgs),
    /// One client of `bench load --chaos-every` (a process of its own, to be killed).
    #[command(hide = true)]
    LoadClient(LoadClientArgs),
    /// The 1 kHz haptic path over shared memory: null loop, iceoryx2 round trip, full tick.
    #[command(
        long_about = "The 1 kHz haptic path on this machine, each figure beside a null loop measured in the \
same run: (1) the device bridge's timing loop with no IPC and no work; (2) the bridge against an \
echo peer over iceoryx2 shared memory (the iceoryx2 round trip); (3) the bridge's simulated \
stylus palpating the built-in organ against a real session (the full tick). Reports device \
read -> force written, deadline -> force written (compare with the null loop), deadline misses \
and the CPU of the bridge's and the peer's threads.\n\n\
--hog N adds N threads of busy work for the whole run; --wait and --peer-wait choose the wait \
strategies (sleep, spin, hybrid)."
    )]
    Haptic(BenchHapticArgs),
    /// The large-deformation solver against seed 004 Table 5.2 (neo-Hookean cube).
    #[command(
        long_about = "The full-order large-deformation solver (total Lagrangian hexahedra, Newton-Raphson) \
against seed 004 Table 5.2: a 0.1 m Abaqus neo-Hookean cube (E = 3000 Pa, nu = 0.49), face y = 0 \
clamped, face y = 0.1 m pulled 0.02 m with its x and z motion fixed; Abaqus (17,576 nodes, \
hybrid elements) gives 0.06477 J and 6.109 N. Each --cells size runs with the mean-dilatation \
element and with full integration (which locks); then --stretch values on --range-cells."
    )]
    Cube(BenchCubeArgs),
    /// ANM-POD (seed 001) against full Newton-Raphson on a scene: load-displacement curves of
    /// orders 1-6, the continuation, a plot, and the online cost.
    #[command(
        long_about = "Seed 001's reduced large-deformation model on a scene's load case, against the full \
model on the same mesh. The organ is solved with St Venant-Kirchhoff (its E and nu) by full \
Newton-Raphson in --steps load steps; their states are the POD snapshots (--modes at most); \
the reduced model's tensors are built; then one asymptotic series from the unloaded state per \
--orders (tangent at the origin for the whole curve, as the seed), the continuation at order 6 \
(new series at each validity radius) and the exact reduced equilibrium are compared with Newton \
under the load at every load step. Writes the load-displacement plot (SVG) and prints the table, \
the displacement each order reaches within 5 %, and the online cost per evaluation (p50/p99) \
beside a null loop measured in the same run.\n\n\
With --lattice SIDE, the same load (spread over the nodes within the probe's radius) is also \
applied at the SIDE x SIDE positions of a lattice around the load point and at positions between \
them; the reduced bases of the four nearest lattice positions are interpolated (nearest only, PODI, \
Grassmann) and the resulting reduced models are compared with full Newton there.\n\n\
Default scene: the built-in cornea. The seed's liver: vademecum bench anm scenes/liver_palpation_large.toml"
    )]
    Anm(BenchAnmArgs),
    /// The meshless solver (seed 004, EFG + adaptive dynamic relaxation) against Table 3.2.
    #[command(
        long_about = "The meshless reference solver (element-free Galerkin with MLS shape functions, total \
Lagrangian Abaqus neo-Hookean, adaptive dynamic relaxation) on seed 004's 0.1 m square in plane \
strain (E = 3000 Pa, nu = 0.49), edge x = 0 clamped, edge x = 0.1 m pulled 20 % with its y motion \
fixed; Abaqus (1,681 nodes) gives 0.847 J and 77.64 N per metre of thickness. Each --nodes size \
runs with each --threads count and each --integration density (run time, relaxation steps); then \
--stretch values on --range-nodes; then the 3D cube of Table 5.2 (0.06477 J, 6.109 N) at \
--cube-nodes with each --threads count, and at the --stretch values on --cube-range-nodes.\n\n\
Cutting (seed 004 section 4.3): the stretched square is cut along A(0.05, 0.09) B(0.059, 0.082) \
C(0.066, 0.075) D(0.058, 0.052) (points on the stretched body, traced back to the material points \
there; the cut enters from the top edge through A) in three stages, relaxed after each; Abaqus \
(pre-cut square, 7,813 nodes) gives 0.507 J and 46.91 N. Each --cut-nodes size runs with regular \
nodes and with nodes refined around the cut; --plot draws the cut specimen."
    )]
    Efg(BenchEfgArgs),
    /// Reduced online cutting (PRB, SRB; bare or local fields) against the full XFEM.
    #[command(long_about = "The reduced online cutting models of seed 000 (sections 3.2-3.3) against the \
full-order XFEM on the same mesh and cut: the PGD modes of the organ's vademecum as a Ritz basis, \
parametric (PRB, one coefficient per mode) or spatial (SRB, one per mode and component), with the \
bare enrichment or the seed's local discontinuous fields. Along the scene's pre-planned cuts, one \
blade position at a time: the relative L2 error of the displacement (both lips of every node) and \
the opening. At the final cut: the error against the number of modes (--modes; a plot). Then the \
tick cost (the cut organ's contact compliance) at --enriched nodes, cut along planes through the \
organ, beside a null loop, with the time to enrich one node and the memory.")]
    Cut(BenchCutArgs),
    /// Tearing by continuum damage (seed 000 ch. 4): the POD–PGD integrator against the
    /// full-order references, per step; dissipated energy; online step cost.
    #[command(long_about = "Tearing by continuum damage (seed 000, chapter 4) on a scene with a damage \
material and [fidelity.tearing]: the offline stage (the explicit full-order references with h = 0 and \
with the consistent tangent, POD of their damage fields, the PGD vademecum over the POD coefficients), \
a Newton reference (equilibrium at every step), then both online integrators (the seed's simplified \
h = 0 and the full h != 0) over the scene's schedule. Prints per step the relative L2 error of each \
integrator against its reference and the explicit scheme's distance from Newton, the damage and the torn \
cells; the energy dissipated by each; the online step cost p50/p99 (and rebuilding the whole \
displacement field, as a frame does) beside a null loop; memory. Writes two SVG plots: the error per \
step, and the load against the load-weighted displacement (for cube_shear: the shear stress-strain \
curve).\n\n\
Default scene: the built-in cube_tear; also --builtin cube_shear and --builtin gallbladder_fat.")]
    Tear(BenchTearArgs),
    /// One equilibrium iteration of the co-rotational XFEM on tetrahedral meshes, with cuts.
    #[command(long_about = "What one equilibrium iteration of the co-rotational XFEM (seed 003 §3.1; \
docs/cutting.md) costs: the elastic forces (a polar decomposition per side of every cell), the warped \
stiffness, its Cholesky factorization (symbolic analysis once) and the solve, p50 of --iterations \
each, for every MESH with each number of cut cells in --cuts (the cells nearest the mesh's centre \
that a plane through it crosses), beside a null loop.\n\n\
Default mesh: a built-in 24 x 6 x 6 block of tetrahedra. The liver of the issue: \
../shared/data/meshes/derived/openhelp_liver_tet_h20.msh and _h12.msh.")]
    Corot(BenchCorotArgs),
    /// What each effect costs: build time, bundle size, session memory and tick work per scene.
    #[command(long_about = "Effect composition: for each SCENE (default: the cornea of seed 001 with \
palpation only, + large deformations, + cutting, + tearing: scenes/effects/cornea_*.toml), build its \
bundles into a fresh folder (timed), measure the bundle's size on disk, then run its headless session \
(`vademecum run`, the scene's built-in trajectory at 1 kHz) and read the session's tick work \
percentiles, deadline misses and the memory it holds of its own, by effect. Prints one row per scene \
and the difference of each to the first (the palpation-only baseline).\n\n\
Builds and runs in child processes of this binary, one scene at a time; --out keeps the bundles and \
recordings (default: a temporary folder, removed).")]
    Effects(BenchEffectsArgs),
}

/// Arguments of `vademecum bench tear`.
#[derive(Debug, Args)]
pub struct BenchTearArgs {
    /// Scene file (TOML) with a tearable material. Default: the built-in scene named by --builtin.
    pub scene: Option<PathBuf>,
    /// Built-in scene to use when no SCENE is given.
    #[arg(long, default_value = "cube_tear", conflicts_with = "scene", value_parser = builtin_names())]
    pub builtin: String,
    /// Passes over the schedule when timing the online step.
    #[arg(long, default_value_t = 200)]
    pub passes: usize,
    /// Folder of the plots. Default: `out/<scene>/`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Instead of a scene: the homogeneous unit cube in uniaxial strain, loaded, unloaded
    /// and reloaded, by Newton against the closed-form curves of both damage laws (the
    /// seed's Simó law and the threshold/softening form through its peak); writes this SVG.
    #[arg(long, value_name = "SVG", conflicts_with = "scene")]
    pub closed_form: Option<PathBuf>,
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench corot`.
#[derive(Debug, Args)]
pub struct BenchCorotArgs {
    /// Tetrahedral meshes (Gmsh, VTK). Default: a built-in block.
    pub meshes: Vec<PathBuf>,
    /// Cut cells to time with.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0, 10, 50, 200])]
    pub cuts: Vec<usize>,
    /// Timed calls of each part.
    #[arg(long, default_value_t = 10)]
    pub iterations: usize,
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench effects`.
#[derive(Debug, Args)]
pub struct BenchEffectsArgs {
    /// Scene files (TOML), the first the baseline. Default: scenes/effects/cornea_{palpation,large,cutting,tearing,large_cutting}.toml.
    pub scenes: Vec<PathBuf>,
    /// Seconds of each session (default: the length of the scene's built-in trajectory).
    #[arg(long, value_name = "S")]
    pub seconds: Option<f64>,
    /// Keep the bundles and recordings here.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench cut`.
#[derive(Debug, Args)]
pub struct BenchCutArgs {
    /// Scene file (TOML) with pre-planned cuts. Default: the built-in scene named by --builtin.
    pub scene: Option<PathBuf>,
    /// Built-in scene to use when no SCENE is given.
    #[arg(long, default_value = "keratotomy", conflicts_with = "scene", value_parser = builtin_names())]
    pub builtin: String,
    /// PGD tolerance of the vademecum (seed 000 uses 1e-4).
    #[arg(long, default_value_t = 1e-4)]
    pub tolerance: f64,
    /// Most PGD modes.
    #[arg(long, default_value_t = 300)]
    pub max_modes: usize,
    /// Mode counts of the error-against-modes sweep (capped at the vademecum's).
    #[arg(long, value_delimiter = ',', default_values_t = vec![5, 10, 20, 40, 54, 80, 120, 200])]
    pub modes: Vec<usize>,
    /// Enriched-node counts at which the tick is timed.
    #[arg(long, value_delimiter = ',', default_values_t = vec![16, 64, 256])]
    pub enriched: Vec<usize>,
    /// Ticks timed per figure.
    #[arg(long, default_value_t = 20_000)]
    pub ticks: usize,
    /// Skip the session part (the cutting pipeline's tick against a palpation scene's, the
    /// scalpel drawing the scene's cuts at 1 kHz, the forces against the full XFEM).
    #[arg(long)]
    pub no_session: bool,
    /// Where to write the error-against-modes plot. Default: `out/<scene>/cut_modes.svg`.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench efg`.
#[derive(Debug, Args)]
pub struct BenchEfgArgs {
    /// Nodes per edge of the squares compared with the seed.
    #[arg(long, value_delimiter = ',', default_values_t = vec![11, 21, 31, 41])]
    pub nodes: Vec<usize>,
    /// Thread counts to time each size with.
    #[arg(long, value_delimiter = ',', default_values_t = vec![1, 2])]
    pub threads: Vec<usize>,
    /// Stretches (fraction of the edge) of the range study.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.4, 0.6, 0.8, 1.0])]
    pub stretch: Vec<f64>,
    /// Nodes per edge of the range study.
    #[arg(long, default_value_t = 21)]
    pub range_nodes: usize,
    /// Nodes per edge of seed 004's 3D cube (Table 5.2), run with 2 x 2 x 2 points per cell
    /// and the last --threads count (none: skip the cube).
    #[arg(long, value_delimiter = ',', default_values_t = vec![11, 13, 15])]
    pub cube_nodes: Vec<usize>,
    /// Integration points per cell side: 1 (the seed's one point per cell) and/or 2 (2 x 2).
    #[arg(long, value_delimiter = ',', default_values_t = vec![1, 2])]
    pub integration: Vec<usize>,
    /// Nodes per edge of the cube's stretch range study (none: skip it).
    #[arg(long)]
    pub cube_range_nodes: Option<usize>,
    /// Nodes per edge of the cutting study of Fig. 4.8 (none: skip it).
    #[arg(long, value_delimiter = ',', default_values_t = vec![41, 61])]
    pub cut_nodes: Vec<usize>,
    /// Also start the cut at A itself, leaving the 0.05 mm ligament between A and the edge.
    #[arg(long)]
    pub cut_at_a: bool,
    /// Draw the cut specimen at the end of cutting (SVG), from the first --cut-nodes size.
    #[arg(long, value_name = "SVG")]
    pub plot: Option<PathBuf>,
    /// Print the rows as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench anm`.
#[derive(Debug, Args)]
pub struct BenchAnmArgs {
    /// Scene file (TOML). Default: the built-in scene named by --builtin.
    pub scene: Option<PathBuf>,
    /// Built-in scene to use when no SCENE is given.
    #[arg(long, default_value = "cornea", conflicts_with = "scene", value_parser = builtin_names())]
    pub builtin: String,
    /// Full Newton-Raphson load steps (snapshots and comparison points).
    #[arg(long, default_value_t = 12)]
    pub steps: usize,
    /// Most POD modes (seed 001 uses 9).
    #[arg(long, default_value_t = 9)]
    pub modes: usize,
    /// Multiply the scene's loads by this (full Newton stops early, and the comparison with
    /// it, if it fails to converge before).
    #[arg(long, default_value_t = 1.0)]
    pub load_multiplier: f64,
    /// Orders of the one-series curves (1-8).
    #[arg(long, value_delimiter = ',', default_values_t = vec![1, 2, 3, 4, 5, 6])]
    pub orders: Vec<usize>,
    /// Also interpolate reduced models between the positions of a SIDE x SIDE lattice around
    /// the load point and compare with full Newton at positions off the lattice (nearest
    /// neighbour, PODI, Grassmann).
    #[arg(long, value_name = "SIDE")]
    pub lattice: Option<usize>,
    /// Spacing of the lattice (m). Default: a tenth of the organ's size.
    #[arg(long)]
    pub spacing: Option<f64>,
    /// Enrich each lattice basis with the linear responses to the load at the accessible nodes
    /// within one spacing (so that it spans the loads around its position).
    #[arg(long)]
    pub enrich: bool,
    /// Where to write the load-displacement plot. Default: `out/<scene>/anm.svg`.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Online evaluations timed per figure.
    #[arg(long, default_value_t = 20_000)]
    pub calls: usize,
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench cube`.
#[derive(Debug, Args)]
pub struct BenchCubeArgs {
    /// Cells per edge of the meshes compared with the seed at 20 % stretch.
    #[arg(long, value_delimiter = ',', default_values_t = vec![12, 15, 20, 25])]
    pub cells: Vec<usize>,
    /// Stretches (fraction of the edge) of the range study.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.4, 0.6, 0.8, 1.0])]
    pub stretch: Vec<f64>,
    /// Cells per edge of the range study (mean-dilatation hexahedra: run when they are among
    /// --elements).
    #[arg(long, default_value_t = 12)]
    pub range_cells: usize,
    /// The elements timed and compared (comma-separated; default: all four).
    #[arg(long, value_delimiter = ',', value_enum)]
    pub elements: Vec<CubeElement>,
    /// Print the rows as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench haptic`.
#[derive(Debug, Args)]
pub struct BenchHapticArgs {
    /// Seconds per phase.
    #[arg(long, default_value_t = 60.0)]
    pub seconds: f64,
    /// How the bridge waits for its deadlines (sleep, spin, hybrid).
    #[arg(long, default_value = "hybrid")]
    pub wait: vademecum_bridge::timing::WaitStrategy,
    /// How the peer (echo or session tick thread) waits for the bridge's states (sleep,
    /// spin, hybrid, event).
    #[arg(long, default_value = "hybrid")]
    pub peer_wait: vademecum_bridge::timing::WaitStrategy,
    /// Spin window of the hybrid waits (µs).
    #[arg(long, default_value_t = 200, value_name = "US")]
    pub spin_window_us: u64,
    /// Threads of busy work running during the whole benchmark.
    #[arg(long, default_value_t = 0)]
    pub hog: usize,
    /// Ask for SCHED_FIFO for the bridge (80) and the peer (70) threads, as the bridge and
    /// haptic sessions do (not with the spin wait).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub realtime: bool,
    /// Folder of the organ's bundle (built there when missing). Default: out/organ.
    #[arg(long, value_name = "DIR")]
    pub bundles: Option<PathBuf>,
    /// Where the peer's hybrid wait expects the next state: `schedule` (the bridge's tracked
    /// schedule, the default) or `last-seen` (a period after the last state seen: the method
    /// before 2026-12-02, to measure against).
    #[arg(long, default_value = "schedule", value_name = "SOURCE")]
    pub peer_phase: vademecum_bridge::peer::PhaseSource,
    /// Pin the bridge thread to the last CPU and the peer (echo or tick thread) to the one
    /// before it, so the two real-time threads never share a core.
    #[arg(long)]
    pub pin: bool,
    /// Hold the bridge's CPU wake-up latency request (PM QoS 0 µs: idle CPUs poll instead of
    /// halting) during every phase, as `vademecum-bridge` does by default; `false` to measure
    /// without it.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub wake_latency: bool,
    /// Runs of the three phases; with more than one, the summary gives the median and the
    /// spread over the runs and how many runs meet the haptic goal.
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub repeat: usize,
    /// Run real co-tenant processes beside the loop for the whole benchmark: this
    /// executable's `solve` and `build` of the built-in organ, restarted as they finish.
    #[arg(long)]
    pub cotenant: bool,
    /// Write every tick of every phase as CSV into DIR (`run<k>_<phase>.csv`: the bridge's
    /// trace with the server's wait times).
    #[arg(long, value_name = "DIR")]
    pub trace: Option<PathBuf>,
    /// A fourth phase: two hands — the organ with a second probe (its bundle built beside the
    /// organ's when missing), a bridge on each tool's channel, both palpating; each bridge's
    /// figures beside the null loop's.
    #[arg(long)]
    pub two_hands: bool,
    /// Print the results as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench session`.
#[derive(Debug, Args)]
pub struct BenchSessionArgs {
    /// Seconds per measurement.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Numbers of concurrent sessions to try.
    #[arg(long, value_delimiter = ',', default_values_t = vec![1, 2, 4, 8])]
    pub concurrent: Vec<usize>,
    /// Folder of the organ's bundle (built there when missing). Default: out/organ.
    #[arg(long, value_name = "DIR")]
    pub bundles: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `vademecum bench load`.
#[derive(Debug, Args)]
pub struct BenchLoadArgs {
    /// Sessions on the server.
    #[arg(long, default_value_t = 32)]
    pub sessions: usize,
    /// Interaction streams per session.
    #[arg(long, default_value_t = 1)]
    pub clients_per_session: usize,
    /// Viewers (30 Hz) per session.
    #[arg(long, default_value_t = 1)]
    pub viewers: usize,
    /// Seconds under load.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Tool states per second each client sends (each after the previous answer).
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    pub rate: f64,
    /// Tick workers of the server (its default: one per CPU; 0: a thread per session).
    #[arg(long, value_name = "N")]
    pub tick_workers: Option<usize>,
    /// Frame workers of the server (its default: one per CPU; 0: a thread per session).
    #[arg(long, value_name = "N")]
    pub frame_workers: Option<usize>,
    /// Sample the server's RSS and the misses of sessions and null loop every this many
    /// seconds (a soak's time series: growth shows as a trend across windows).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    pub window: f64,
    /// Chaos: after the first window, kill -9 a random client every this many seconds (the
    /// clients of the first --chaos-clients sessions run as processes of their own) and start
    /// a new one on its session; the other sessions' misses are reported apart.
    #[arg(long, value_name = "SECONDS")]
    pub chaos_every: Option<f64>,
    /// Sessions whose client runs as a killable process, with --chaos-every.
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub chaos_clients: usize,
    /// Of the sessions, this many are driven by a device bridge (`vademecum-bridge`, a
    /// simulated stylus over shared memory, one process each; built beside this executable)
    /// instead of a gRPC client. With --chaos-every, one bridge is killed (SIGKILL) once, half
    /// way through, and restarted.
    #[arg(long, default_value_t = 0, value_name = "K")]
    pub haptic: usize,
    /// How the server's device sessions wait for their bridges (serve --haptic-wait).
    #[arg(long, default_value = "event", value_name = "WAIT")]
    pub haptic_wait: vademecum_bridge::timing::WaitStrategy,
    /// Device workers of the server (serve --device-workers; its default 0: a thread per
    /// device session). Needs --haptic-wait event.
    #[arg(long, value_name = "N")]
    pub device_workers: Option<usize>,
    /// How the bridges wait for each answer (vademecum-bridge --answer-wake): `event`
    /// (blocked on the server's event: many bridges share the cores) or `poll`.
    #[arg(long, value_enum, default_value_t = vademecum_bridge::bridge_loop::AnswerWake::Event)]
    pub bridge_answer_wake: vademecum_bridge::bridge_loop::AnswerWake,
    /// Have the server hold a CPU wake-up latency request (serve --wake-latency-us).
    #[arg(long, value_name = "US")]
    pub server_wake_latency_us: Option<u32>,
    /// The device bridge executable for --haptic (default: `vademecum-bridge` beside this one).
    #[arg(long, value_name = "PATH")]
    pub bridge: Option<PathBuf>,
    /// The built-in scene every session plays: `organ` (a probe circling over it and pressing
    /// in and out), or a tearing scene (`cube_tear`, `gallbladder_fat`: a grasper holding the
    /// scene's grasp and pulling it along its direction until the force reaches half the
    /// grasper's max_force, then back, over and over). --haptic and --chaos-every drive the
    /// organ only.
    #[arg(long, default_value = "organ", value_name = "NAME")]
    pub builtin: String,
    /// Folder of the scene's bundle (built there when missing). Default: out/NAME.
    #[arg(long, value_name = "DIR")]
    pub bundles: Option<PathBuf>,
    /// Also write the figures as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Threads of busy floating-point work beside the server (in this process) while the load
    /// runs: a CPU hog, to show the sessions' fidelity fallback (their cheaper setting under
    /// load, `fidelity.fallback`) and their return when it stops.
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub hog: usize,
    /// With --hog: stop the hog after this many seconds of the load (default: the whole run).
    #[arg(long, value_name = "SECONDS")]
    pub hog_seconds: Option<f64>,
    /// Serve with --no-fidelity-fallback: the same load with the sessions kept at their
    /// scenes' settings (the control of a fallback run).
    #[arg(long)]
    pub no_fidelity_fallback: bool,
}

/// Arguments of `vademecum bench load-client` (hidden).
#[derive(Debug, Args)]
pub struct LoadClientArgs {
    /// The server (http://host:port).
    #[arg(long)]
    pub addr: String,
    /// The session to drive.
    #[arg(long)]
    pub session: String,
    /// Tool states per second.
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    pub rate: f64,
}

/// Arguments of `vademecum bench pgd`.
#[derive(Debug, Args)]
pub struct BenchPgdArgs {
    /// Bundle folder (written by `vademecum build`).
    pub bundle: PathBuf,
    /// Contact-force evaluations to time.
    #[arg(long, default_value_t = 200_000)]
    pub contacts: usize,
    /// Field evaluations to time (each for the whole mesh and for the surface).
    #[arg(long, default_value_t = 300)]
    pub fields: usize,
    /// Also time the f32 node-major surface field on synthetic modes of this many surface
    /// nodes (a 30k-node organ has about 10k), with the bundle's number of modes.
    #[arg(long, default_value_t = 10_000)]
    pub surface_nodes: usize,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Cell kinds on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CellArg {
    /// Trilinear hexahedra.
    Hex8,
    /// Linear tetrahedra (6 per cube).
    Tet4,
}

/// Arguments of `vademecum bench fe`.
#[derive(Debug, Args)]
pub struct BenchFeArgs {
    /// Target numbers of degrees of freedom, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "5000,30000,100000")]
    pub dofs: Vec<usize>,
    /// Cell kind.
    #[arg(long, value_enum, default_value = "hex8")]
    pub cell: CellArg,
    /// Repetitions per size (the median is reported).
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn solve_defaults_to_the_organ_scene() {
        let c = Cli::parse_from(["vademecum", "solve"]);
        let Command::Solve(a) = c.command else { panic!("not solve") };
        assert_eq!(a.source.builtin, "organ");
        assert!(a.source.scene.is_none());
    }

    #[test]
    fn bench_sizes_parse_as_a_list() {
        let c = Cli::parse_from(["vademecum", "bench", "fe", "--dofs", "100,200"]);
        let Command::Bench(BenchCommand::Fe(a)) = c.command else {
            panic!("not bench")
        };
        assert_eq!(a.dofs, vec![100, 200]);
    }
}

/// An element of `bench cube --elements`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CubeElement {
    /// Hexahedra with the mean-dilatation volumetric term (also the range study's).
    Hex8MeanDilatation,
    /// Hexahedra, full integration.
    Hex8Full,
    /// Tetrahedra with the averaged nodal pressure.
    Tet4Nodal,
    /// Plain tetrahedra.
    Tet4Plain,
}
