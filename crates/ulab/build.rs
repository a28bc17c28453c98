//! Stamps the binary with the commit it was built from (`ULAB_GIT_COMMIT`): a sharded campaign's shard files carry it,
//! so that `ulab merge` refuses shards that different versions of the code produced. Outside a git checkout (a source
//! tarball) the commit is `unknown`.
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok().filter(|o| o.status.success())?;
    let s = String::from_utf8(out.stdout).ok()?.trim().to_owned();
    (!s.is_empty()).then_some(s)
}

fn main() {
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).unwrap_or_else(|| "unknown".to_owned());
    println!("cargo:rustc-env=ULAB_GIT_COMMIT={commit}");
    // A new commit moves HEAD or the branch it names (a loose ref, or packed-refs); rebuild the stamp then. Only
    // files that exist are named: cargo reruns a script whose named file is missing at every build.
    let mut watched = vec![git(&["rev-parse", "--git-path", "HEAD"]), git(&["rev-parse", "--git-path", "packed-refs"])];
    if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
        watched.push(git(&["rev-parse", "--git-path", &branch]));
    }
    for path in watched.into_iter().flatten().filter(|p| std::path::Path::new(p).exists()) {
        println!("cargo:rerun-if-changed={path}");
    }
    if commit == "unknown" {
        println!("cargo:rerun-if-changed=build.rs");
    }
}
