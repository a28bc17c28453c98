#!/bin/bash -eu
# ClusterFuzzLite / OSS-Fuzz build script: builds the protocol fuzz targets of fuzz/ and copies them, with seed corpora
# zipped from fuzz/corpus/<target>/seeds and .../regressions (what is committed, not what a local `cargo fuzz run`
# added beside them), into $OUT.
#
# On the service (base-builder-rust) `cargo fuzz build -O` builds with the service's sanitizer and coverage flags.
# Locally with cargo-fuzz (scripts/setup.sh --fuzz) the same, on the nightly toolchain. Without cargo-fuzz (CI's
# stable-Rust machines) it falls back to scripts/fuzz.sh's stable build, which asks rustc for the same coverage
# instrumentation without the address sanitizer. Both were run locally (see README.md).
# On the service this runs as $SRC/build.sh with the sources in $SRC/ulab; locally as .clusterfuzzlite/build.sh.
if [ -d "${SRC:-/nonexistent}/ulab/fuzz" ]; then cd "$SRC/ulab"; else cd "$(dirname "$0")/.."; fi
: "${OUT:?set OUT to the output directory}"
TARGETS=(decode_any crc roundtrip)
if cargo fuzz --help >/dev/null 2>&1; then
  # cargo fuzz's sanitizer build needs nightly: the service's default toolchain; elsewhere an installed nightly.
  if [ -z "${RUSTUP_TOOLCHAIN:-}" ] && ! rustc --version | grep -q nightly \
    && cargo +nightly --version >/dev/null 2>&1; then
    export RUSTUP_TOOLCHAIN=nightly
  fi
  for t in "${TARGETS[@]}"; do cargo fuzz build -O "$t"; done
else
  bash scripts/fuzz.sh build-protocol
fi
BIN=fuzz/target/x86_64-unknown-linux-gnu/release
mkdir -p "$OUT"
for t in "${TARGETS[@]}"; do
  cp "$BIN/$t" "$OUT/$t"
  seeds=$(mktemp -d)
  for d in "fuzz/corpus/$t/seeds" "fuzz/corpus/$t/regressions"; do
    if [ -d "$d" ]; then find "$d" -maxdepth 1 -type f ! -name '*.md' -exec cp {} "$seeds/" \;; fi
  done
  if [ -n "$(ls -A "$seeds")" ]; then (cd "$seeds" && zip -q -r "$OUT/${t}_seed_corpus.zip" .); fi
  rm -rf "$seeds"
done
echo "build.sh: ${TARGETS[*]} in $OUT"
