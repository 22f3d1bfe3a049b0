//! `vademecum check hard-cases`: the engine's hard-case suite ([`vademecum_engine::check`]) with
//! a progress bar, printed as a table (text or Markdown) and optionally written as JSON.

use std::io::Write;
use std::process::ExitCode;

use anyhow::Context;
use vademecum_engine::check::{self, Outcome, Size, Verdict};

use crate::cli::HardCasesArgs;

/// What a verdict's outcome says, in one cell: the answer or the diagnostic.
fn said(v: &Verdict) -> String {
    match &v.outcome {
        Outcome::Answer { summary, .. } => summary.clone(),
        Outcome::Diagnostic(m) => format!("diagnostic: {m}"),
        Outcome::Broken(m) => format!("BROKEN: {m}"),
    }
}

fn error(v: &Verdict) -> String {
    match v.outcome {
        Outcome::Answer { error: Some(e), .. } => check::percent(e),
        _ => "–".into(),
    }
}

fn verdict(v: &Verdict) -> &'static str {
    if v.pass { "ok" } else { "FAIL" }
}

fn json(v: &Verdict) -> serde_json::Value {
    let (kind, text, err) = match &v.outcome {
        Outcome::Answer { summary, error } => ("answer", summary, *error),
        Outcome::Diagnostic(m) => ("diagnostic", m, None),
        Outcome::Broken(m) => ("broken", m, None),
    };
    serde_json::json!({
        "case": v.name, "method": v.method, "expected": v.expected, "outcome": kind,
        "says": text, "relative_error": err, "seconds": v.seconds, "pass": v.pass,
    })
}

/// Runs the suite (or the cases `--only` picks) and prints the verdicts; exit status 1 when a
/// case fails.
pub fn hard_cases(a: HardCasesArgs) -> anyhow::Result<ExitCode> {
    let size = if a.reduced { Size::Reduced } else { Size::Full };
    let only = a.only.as_deref().map(str::to_lowercase);
    let cases: Vec<_> = check::cases()
        .into_iter()
        .filter(|c| {
            only.as_deref()
                .is_none_or(|o| c.name.to_lowercase().contains(o) || c.method.to_lowercase().contains(o))
        })
        .collect();
    anyhow::ensure!(!cases.is_empty(), "no hard case matches --only {:?}", a.only.unwrap_or_default());
    let mut bar = crate::progress::Steps::start("check hard-cases", cases.len());
    bar.step(&format!("{} / {}", cases[0].name, cases[0].method));
    let verdicts = check::run(&cases, size, |i, v| {
        if !v.pass {
            bar.println(&format!("FAIL {} / {}: {}", v.name, v.method, said(v)));
        }
        if let Some(next) = cases.get(i + 1) {
            bar.step(&format!("{} / {}", next.name, next.method));
        }
    });
    bar.finish();

    let mut out = std::io::stdout().lock();
    if a.markdown {
        writeln!(out, "| case | method | expected | outcome | error | time (s) | verdict |")?;
        writeln!(out, "|---|---|---|---|---|---|---|")?;
        for v in &verdicts {
            let cell = |s: &str| s.replace('|', "\\|");
            writeln!(
                out,
                "| {} | {} | {} | {} | {} | {:.2} | {} |",
                cell(v.name),
                cell(v.method),
                cell(&v.expected),
                cell(&said(v)),
                error(v),
                v.seconds,
                verdict(v)
            )?;
        }
    } else {
        for v in &verdicts {
            // the verdict beside what it checked: "ok" on a locked cantilever's 97 % error means
            // the answer is finite (and the lock diagnosed), not that 97 % is fine
            writeln!(out, "{:4} {} — {} (checked: {})", verdict(v), v.name, v.method, v.expected)?;
            writeln!(out, "     {} [error {}, {:.2} s]", said(v), error(v), v.seconds)?;
        }
    }
    let failed = verdicts.iter().filter(|v| !v.pass).count();
    let total: f64 = verdicts.iter().map(|v| v.seconds).sum();
    writeln!(
        out,
        "\n{} of {} hard cases pass ({} size, {total:.1} s){}",
        verdicts.len() - failed,
        verdicts.len(),
        if a.reduced { "reduced" } else { "full" },
        if failed > 0 { format!("; {failed} FAIL") } else { String::new() }
    )?;
    if let Some(path) = &a.json {
        let doc = serde_json::json!({
            "size": if a.reduced { "reduced" } else { "full" },
            "cases": verdicts.iter().map(json).collect::<Vec<_>>(),
        });
        std::fs::write(path, serde_json::to_string_pretty(&doc)?).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(if failed > 0 { ExitCode::FAILURE } else { ExitCode::SUCCESS })
}
