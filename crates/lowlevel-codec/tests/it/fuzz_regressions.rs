//! Replays every saved fuzz input (`fuzz/corpus/<target>/regressions/`, minimized crashes and
//! hand-made nasty inputs) and the seed corpora (`fuzz/corpus/<target>/seeds/`) through the exact
//! checks the fuzz targets run. Only these committed folders: the inputs a local `cargo fuzz run` wrote
//! beside them are not replayed.

use lowlevel_codec::fuzzing;
use std::path::Path;

fn replay(target: &str, check: fn(&[u8])) -> usize {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus").join(target);
    let mut count = 0;
    for dir in [root.join("regressions"), root.join("seeds")] {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for entry in entries {
            let path = entry.expect("entry").path();
            if path.is_file() && path.extension().is_none_or(|e| e != "md") {
                let bytes = std::fs::read(&path).expect("read");
                let result = std::panic::catch_unwind(|| check(&bytes));
                assert!(result.is_ok(), "{target} fails on {}", path.display());
                count += 1;
            }
        }
    }
    count
}

#[test]
fn decode_any_regressions() {
    assert!(replay("decode_any", fuzzing::decode_any) > 0, "no decode_any inputs found");
}

#[test]
fn crc_regressions() {
    assert!(replay("crc", fuzzing::crc_fast_equals_reference) > 0, "no crc inputs found");
}

#[test]
fn roundtrip_regressions() {
    assert!(replay("roundtrip", fuzzing::roundtrip_bytes) > 0, "no roundtrip inputs found");
}
