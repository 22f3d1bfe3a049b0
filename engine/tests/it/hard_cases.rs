//! The hard-case suite (`vademecum check hard-cases`) at reduced size: every method through
//! its numerically hard inputs must give a finite, bounded answer within the case's error, or
//! the typed diagnostic the case names (`docs/stability.md`).

use vademecum_engine::check::{self, Outcome, Size};

#[test]
fn every_hard_case_answers_or_says_why() {
    let cases = check::cases();
    let verdicts = check::run(&cases, Size::Reduced, |_, v| {
        let outcome = match &v.outcome {
            Outcome::Answer { summary, error } => {
                format!(
                    "{summary}{}",
                    error.map(|e| format!(" [error {}]", check::percent(e))).unwrap_or_default()
                )
            }
            Outcome::Diagnostic(m) => format!("diagnostic: {m}"),
            Outcome::Broken(m) => format!("BROKEN: {m}"),
        };
        eprintln!(
            "{} {} | {} | {outcome} ({:.2} s)",
            if v.pass { "ok  " } else { "FAIL" },
            v.name,
            v.method,
            v.seconds
        );
    });
    let failed: Vec<String> = verdicts
        .iter()
        .filter(|v| !v.pass)
        .map(|v| format!("{} / {}: expected {}, got {:?}", v.name, v.method, v.expected, v.outcome))
        .collect();
    assert!(
        failed.is_empty(),
        "{} of {} hard cases failed:\n{}",
        failed.len(),
        verdicts.len(),
        failed.join("\n")
    );
}
