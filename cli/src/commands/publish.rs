//! `vademecum publish`: bundles into a content-addressed store, under their digest.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use vademecum_engine::bundle::{self, store};

use crate::cli::PublishArgs;

/// The bundle folders named: each given bundle, and every `*.bundle` inside a given folder.
fn bundles(paths: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        if p.join(bundle::MANIFEST).is_file() {
            out.push(p.clone());
            continue;
        }
        let entries = std::fs::read_dir(p).with_context(|| format!("{} is neither a bundle nor a folder of bundles", p.display()))?;
        let mut found: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|e| e.extension().is_some_and(|x| x == "bundle") && e.join(bundle::MANIFEST).is_file())
            .collect();
        anyhow::ensure!(!found.is_empty(), "{} holds no bundle (<organ>.bundle folders)", p.display());
        found.sort();
        out.extend(found);
    }
    Ok(out)
}

/// Publishes the bundles of `paths` into `store_dir`; returns organ → digest.
pub(crate) fn publish(paths: &[PathBuf], store_dir: &Path) -> anyhow::Result<BTreeMap<String, String>> {
    let mut digests = BTreeMap::new();
    for dir in bundles(paths)? {
        let digest = store::publish(&dir, store_dir).with_context(|| format!("cannot publish {}", dir.display()))?;
        let organ = bundle::read_manifest(&dir)?.organ;
        if let Some(other) = digests.insert(organ.clone(), digest.clone())
            && other != digest
        {
            anyhow::bail!("two bundles of organ '{organ}' among those given ({other} and {digest}): publish one scene's at a time");
        }
    }
    Ok(digests)
}

pub fn run(a: PublishArgs) -> anyhow::Result<ExitCode> {
    let digests = publish(&a.bundles, &a.store)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&digests)?);
    } else {
        for (organ, digest) in &digests {
            println!("{organ}: {digest}");
        }
        eprintln!(
            "published in {} (ask for them with CreateSession bundle_digests; serve --bundle-store)",
            a.store.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
