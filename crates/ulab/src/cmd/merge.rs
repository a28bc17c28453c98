//! `ulab merge PATH... --out DIR`: the report of a sharded campaign (issue 62). Each PATH is a shard file or a
//! directory holding `shard-K-of-N.cbor` files written by a campaign command run with `--shard K/N`; the campaign
//! kind comes from the files. The merge checks that the files are every shard of one campaign (same kind, program,
//! configuration and shard count; each shard once, with the items the dealing rule gives it), puts the results
//! back in the unsharded order and runs the campaign's analysis on them: what it writes into DIR is what the
//! unsharded run writes (timings aside), and it exits as that run would. The sharding rules live in the `campaign`
//! crate; `docs/campaigns.md` describes them.
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use campaign::{Shard, ShardFile};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Shard files, or directories holding them (`shard-K-of-N.cbor`).
    #[arg(required = true)]
    paths: Vec<PathBuf>,
    /// Output directory: the files the unsharded run writes.
    #[arg(long)]
    out: PathBuf,
    /// Worker threads of the analysis (default: all cores).
    #[arg(long)]
    jobs: Option<usize>,
}

/// What wrote a shard, with the commit it was built from (`build.rs`): shards of different versions are not merged.
const PRODUCER: &str = concat!("ulab ", env!("CARGO_PKG_VERSION"), " (commit ", env!("ULAB_GIT_COMMIT"), ")");

pub fn run(a: Args) -> Result<Exit> {
    super::diff::set_jobs(a.jobs)?;
    let files = campaign::find(&a.paths)?;
    let first = files.first().context("no shard file")?;
    let header = campaign::read_header(first)?;
    match header.kind.as_str() {
        super::diff::SHARD_KIND => super::diff::merge(&files, &a.out),
        super::diff::FUZZ_SHARD_KIND => super::diff::merge_fuzz(&files, &a.out),
        super::validate::SHARD_KIND => super::validate::merge(&files, &a.out),
        super::gap::SHARD_KIND => super::gap::merge(&files, &a.out),
        other => bail!("{}: unknown campaign kind `{other}`", first.display()),
    }
}

/// Writes one shard's results (`items`: (item, result) in item order) into `out/shard-K-of-N.cbor`.
pub(crate) fn write_shard<C: Serialize, T: Serialize>(
    out: &Path,
    kind: &str,
    shard: Shard,
    total: usize,
    config: C,
    items: Vec<(usize, T)>,
) -> Result<Exit> {
    let n = items.len();
    let file = ShardFile {
        format: campaign::FORMAT_VERSION,
        kind: kind.into(),
        producer: PRODUCER.into(),
        shard,
        total,
        config,
        items,
    };
    let path = campaign::write(out, &file)?;
    println!(
        "shard {shard}: {n} of {total} items in {}; `ulab merge` the {} shards for the report",
        path.display(),
        shard.count()
    );
    Ok(Exit::Success)
}

/// Reads the shard files of a `kind` campaign and merges them: its configuration and every result in item order.
pub(crate) fn read_shards<C: DeserializeOwned + PartialEq, T: DeserializeOwned>(
    files: &[PathBuf],
    kind: &str,
) -> Result<(C, Vec<T>)> {
    let mut shards = Vec::new();
    for f in files {
        shards.push((f.clone(), campaign::read::<C, T>(f, kind)?));
    }
    Ok(campaign::merge(shards)?)
}
