//! The hard-case suite: every method driven through the inputs where numerical methods break
//! (near-incompressibility, large strains, inversion, series beyond their radius, lattices and
//! vademecums queried outside what they were built for, cuts through nodes, pieces cut loose,
//! fully damaged tissue, poisoned tool states), each with the outcome a user may rely on: a
//! finite, bounded answer with its error against a reference, or a typed diagnostic.
//!
//! `vademecum check hard-cases` runs it at full size and prints the table; `cargo test` runs it
//! at reduced size (`engine/tests/it/hard_cases.rs`). `docs/stability.md` holds the verdicts.
//!
//! # Layout
//! - [`Case`], [`Expect`], [`Outcome`], [`Verdict`], [`run`]: the contract and the runner
//!   (a case that panics is a failure of the suite, caught and reported, never a crash).
//! - `locking`: linear elements near and at incompressibility, per element and locking option.
//! - `hyperelastic`: every hyperelastic law stretched 100 % and compressed 50 % against the
//!   exact homogeneous answer; inversion; St Venant–Kirchhoff crushed.
//! - `reduced`: the ANM series past its validity radius, reduced SVK crushed, the
//!   large-deformation lattice outside its positions and beyond its paths.
//! - `meshless`: EFG with a node on a cut, a piece cut loose, ν = 0.499, 100 % stretch.
//! - `tool`: the palpation pipeline under NaN/Inf in every input field, a 10 cm jump in one
//!   tick, inputs at the edge of their range, contact outside the accessible region.
//! - `cutting`: XFEM cuts through nodes to the fixed boundary, a piece cut loose, ν = 0.499,
//!   malformed blades.
//! - `cut_tip`: a cut that ends inside a cell (the crack-tip enrichment): the blade stopping on
//!   a node line, a face, inside a cell, 1e-9 beside them, at the far face; tetrahedra.
//! - `tearing`: a fully damaged layer, ν = 0.499 under damage, the POD–PGD integrator driven
//!   outside its coefficient box.
//! - `composed`: effects on one organ — a flap cut while it deforms largely, pressed on the
//!   cut's lip and line far past the lattice; the composed law against Newton on the split organ.

mod composed;
mod cut_tip;
mod cutting;
mod hyperelastic;
mod locking;
mod meshless;
mod reduced;
mod tearing;
mod tool;

use std::sync::{Arc, Mutex};
use std::time::Instant;

/// How large the cases' problems are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Size {
    /// Small meshes: the whole suite in tens of seconds (what `cargo test` runs).
    Reduced,
    /// The meshes the published verdicts were measured on (`vademecum check hard-cases`).
    Full,
}

impl Size {
    /// `reduced` or `full` value by size.
    pub fn pick<T>(self, reduced: T, full: T) -> T {
        match self {
            Self::Reduced => reduced,
            Self::Full => full,
        }
    }
}

/// What a case produced.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// A finite, bounded answer (`summary` says what it is), with its relative error against
    /// the case's reference where there is one.
    Answer {
        /// The answer in a few words with its figures.
        summary: String,
        /// Relative error against the reference.
        error: Option<f64>,
    },
    /// A typed diagnostic: the method refused or stopped, and said why.
    Diagnostic(String),
    /// Neither: a non-finite or unbounded answer, an untyped failure, or a panic. Always a
    /// failure of the suite.
    Broken(String),
}

impl Outcome {
    /// An answer with a relative error.
    pub fn answer(summary: impl Into<String>, error: f64) -> Self {
        Self::Answer {
            summary: summary.into(),
            error: Some(error),
        }
    }

    /// An answer without a reference.
    pub fn bounded(summary: impl Into<String>) -> Self {
        Self::Answer {
            summary: summary.into(),
            error: None,
        }
    }
}

/// What a case must produce to pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Expect {
    /// A finite answer, within `max_error` of the reference when that is given.
    Answer {
        /// Largest relative error accepted.
        max_error: Option<f64>,
    },
    /// A diagnostic whose message contains one of these.
    Diagnostic(&'static [&'static str]),
    /// Either a finite answer or a diagnostic containing one of these (the method may or may
    /// not reach the answer; it must never return garbage).
    AnswerOrDiagnostic(&'static [&'static str]),
}

impl Expect {
    /// A finite answer, any error.
    pub const FINITE: Self = Self::Answer { max_error: None };

    /// A finite answer within `e` of the reference.
    pub const fn within(e: f64) -> Self {
        Self::Answer { max_error: Some(e) }
    }

    /// Whether `outcome` meets the expectation.
    pub fn met_by(&self, outcome: &Outcome) -> bool {
        let says = |words: &[&str], m: &str| words.iter().any(|w| m.contains(w));
        match outcome {
            Outcome::Broken(_) => false,
            Outcome::Answer { error, .. } => match self {
                Self::Answer { max_error: Some(l) } => error.is_some_and(|e| e.is_finite() && e <= *l),
                Self::Answer { max_error: None } | Self::AnswerOrDiagnostic(_) => error.is_none_or(|e| e.is_finite()),
                Self::Diagnostic(_) => false,
            },
            Outcome::Diagnostic(m) => match self {
                Self::Diagnostic(w) | Self::AnswerOrDiagnostic(w) => says(w, m),
                Self::Answer { .. } => false,
            },
        }
    }

    /// The expectation in words, for the table.
    pub fn describe(&self) -> String {
        match self {
            Self::Answer { max_error: None } => "finite answer".into(),
            Self::Answer { max_error: Some(e) } => format!("answer, error ≤ {}", percent(*e)),
            Self::Diagnostic(w) => format!("diagnostic ({})", w.join(" | ")),
            Self::AnswerOrDiagnostic(w) => format!("answer or diagnostic ({})", w.join(" | ")),
        }
    }
}

/// A relative error as a percentage with two significant figures.
pub fn percent(e: f64) -> String {
    let p = 100.0 * e;
    if p == 0.0 {
        "0 %".into()
    } else if p >= 10.0 {
        format!("{p:.0} %")
    } else if p >= 0.01 {
        format!("{p:.2} %")
    } else {
        format!("{p:.1e} %")
    }
}

/// One hard case.
pub struct Case {
    /// What is done, in a few words.
    pub name: &'static str,
    /// The method (and option) under test.
    pub method: &'static str,
    /// What it must produce.
    pub expect: Expect,
    /// Runs it.
    pub run: fn(Size) -> Outcome,
}

/// A case's result.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The case.
    pub name: &'static str,
    /// Its method.
    pub method: &'static str,
    /// Its expectation in words.
    pub expected: String,
    /// What it produced.
    pub outcome: Outcome,
    /// Whether that meets the expectation.
    pub pass: bool,
    /// Wall time (s).
    pub seconds: f64,
}

/// Every case, in table order.
pub fn cases() -> Vec<Case> {
    [
        locking::cases(),
        hyperelastic::cases(),
        reduced::cases(),
        meshless::cases(),
        tool::cases(),
        cutting::cases(),
        cut_tip::cases(),
        tearing::cases(),
        composed::cases(),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// Runs `cases` at `size`, one after the other; `on_done(i, verdict)` after each. A case that
/// panics is reported as [`Outcome::Broken`] with the panic's message.
pub fn run(cases: &[Case], size: Size, mut on_done: impl FnMut(usize, &Verdict)) -> Vec<Verdict> {
    cases
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let start = Instant::now();
            let outcome = match std::panic::catch_unwind(|| (c.run)(size)) {
                Ok(o) => o,
                Err(p) => {
                    let m = p
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| p.downcast_ref::<String>().cloned())
                        .unwrap_or_default();
                    Outcome::Broken(format!("panicked: {m}"))
                }
            };
            let v = Verdict {
                name: c.name,
                method: c.method,
                expected: c.expect.describe(),
                pass: c.expect.met_by(&outcome),
                outcome,
                seconds: start.elapsed().as_secs_f64(),
            };
            on_done(i, &v);
            v
        })
        .collect()
}

/// A method's typed error as [`Outcome::Diagnostic`] (for `.map_err(diagnostic)?` in the cases).
fn diagnostic(e: impl std::fmt::Display) -> Outcome {
    Outcome::Diagnostic(e.to_string())
}

/// Whether every value is finite.
fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// `|a − b| / |b|`.
fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The value of `size` in `cache`, made by `make` the first time (the bundles and lattices
/// several cases share are built once per process and size).
fn once_per_size<T>(cache: &Mutex<Vec<(Size, Arc<T>)>>, size: Size, make: impl FnOnce() -> Result<T, Outcome>) -> Result<Arc<T>, Outcome> {
    let mut made = cache.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, v)) = made.iter().find(|(s, _)| *s == size) {
        return Ok(v.clone());
    }
    let v = Arc::new(make()?);
    made.push((size, v.clone()));
    Ok(v)
}

/// Built-in scene `name` at `size`: its mesh's `divisions` line replaced by `divisions[0]` at
/// reduced size and `divisions[1]` at full size (one of them is the scene's own).
fn builtin_at(name: &str, size: Size, divisions: [&str; 2]) -> Result<crate::scene::Scene, Outcome> {
    let text = crate::scene::builtin(name).expect("a built-in scene");
    let own = divisions
        .iter()
        .find(|d| text.contains(&format!("divisions = {d}")))
        .unwrap_or_else(|| panic!("the built-in {name}'s mesh has one of {divisions:?}"));
    let text = text.replace(
        &format!("divisions = {own}"),
        &format!("divisions = {}", size.pick(divisions[0], divisions[1])),
    );
    crate::scene::Scene::from_toml(&text, format!("<hard case: {name}>")).map_err(diagnostic)
}

/// The bundle of `scene`'s first organ for `size`, built once per process and size (`cache`:
/// the case family's own) and written and loaded back as a session's.
fn session_bundle(
    cache: &Mutex<Vec<(Size, Arc<crate::bundle::LoadedBundle>)>>,
    scene: &crate::scene::Scene,
    size: Size,
) -> Result<Arc<crate::bundle::LoadedBundle>, Outcome> {
    use crate::offline::{self, BuildOptions};
    once_per_size(cache, size, || {
        let b = offline::build_organ(scene, 0, &BuildOptions::for_scene(scene, true), &mut |_| {}).map_err(diagnostic)?;
        let dir = std::env::temp_dir().join(format!("vademecum-check-{}-{}-{size:?}", scene.spec.scene.name, std::process::id()));
        let loaded = offline::write_bundle(&dir, scene, &b)
            .map_err(diagnostic)
            .and_then(|_| crate::bundle::load_bundle(&dir).map_err(diagnostic));
        let _ = std::fs::remove_dir_all(&dir);
        loaded
    })
}

/// The outcome of a case body written with `?` over [`Outcome`]s.
fn outcome(body: impl FnOnce() -> Result<Outcome, Outcome>) -> Outcome {
    body().unwrap_or_else(|o| o)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expectations_reject_broken_and_mismatched_outcomes() {
        let ans = Outcome::answer("x", 0.01);
        assert!(Expect::within(0.02).met_by(&ans));
        assert!(!Expect::within(0.005).met_by(&ans));
        assert!(Expect::FINITE.met_by(&ans));
        assert!(!Expect::Diagnostic(&["no"]).met_by(&ans));
        assert!(Expect::AnswerOrDiagnostic(&["no"]).met_by(&ans));
        let d = Outcome::Diagnostic("no equilibrium beyond".into());
        assert!(Expect::Diagnostic(&["equilibrium"]).met_by(&d));
        assert!(!Expect::Diagnostic(&["Poisson"]).met_by(&d));
        assert!(!Expect::FINITE.met_by(&d));
        assert!(!Expect::FINITE.met_by(&Outcome::answer("nan", f64::NAN)));
        assert!(!Expect::within(1.0).met_by(&Outcome::bounded("no reference")));
        for e in [Expect::FINITE, Expect::Diagnostic(&[""]), Expect::AnswerOrDiagnostic(&[""])] {
            assert!(!e.met_by(&Outcome::Broken("x".into())));
        }
    }

    #[test]
    fn a_panicking_case_is_reported_broken() {
        let case = Case {
            name: "panics",
            method: "none",
            expect: Expect::FINITE,
            run: |_| panic!("boom"),
        };
        let hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let v = run(&[case], Size::Reduced, |_, _| {});
        std::panic::set_hook(hook);
        assert!(!v[0].pass);
        assert_eq!(v[0].outcome, Outcome::Broken("panicked: boom".into()));
    }
}
