//! Files written by the official Python `mcap` writer (mcap 1.6, `tests/mcap/write_mcap.py`) with zstd (its
//! default), lz4, uncompressed chunks and no chunks, holding Unitree hg messages serialized by Cyclone DDS's Python
//! serializer: [`recording::messages`] reads every message of each with the log time and content the writer
//! printed, and truncated or corrupted compressed files give a typed [`ReadError`], never a panic.
use recording::{messages, ReadError};
use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    p.canonicalize().unwrap_or(p)
}

fn python() -> PathBuf {
    std::env::var_os("ULAB_PYTHON").map_or_else(|| workspace().join(".venv/bin/python"), PathBuf::from)
}

/// Runs the Python writer into a fresh directory; returns its JSON (per form: path and expected messages).
fn write_with_python(name: &str, states: usize) -> serde_json::Value {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(python())
        .arg(workspace().join("tests/mcap/write_mcap.py"))
        .arg(&dir)
        .args(["--states", &states.to_string(), "--chunk-size", "16384"])
        .output()
        .expect("run the Python mcap writer");
    assert!(out.status.success(), "Python writer failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("the writer prints JSON")
}

/// (topic, log time, tick or 0, motor 0 q) of every message, decoded by our codec (NaN q: the bytes do not decode).
fn read_all(bytes: &[u8]) -> Result<Vec<(String, u64, u64, f32)>, ReadError> {
    let mut v = Vec::new();
    for m in messages(bytes)? {
        let m = m?;
        let ty = recording::channel_type_name(&m.channel).unwrap_or_default();
        let (tick, q0) = match ty.as_str() {
            "unitree_hg::msg::dds_::LowState_" => lowlevel_codec::decode::<unitree_idl::hg::LowState_>(&m.data)
                .map_or((0, f32::NAN), |s| (u64::from(s.value.tick), s.value.motor_state[0].q)),
            "unitree_hg::msg::dds_::LowCmd_" => lowlevel_codec::decode::<unitree_idl::hg::LowCmd_>(&m.data)
                .map_or((0, f32::NAN), |c| (0, c.value.motor_cmd[0].q)),
            _ => (0, f32::NAN),
        };
        v.push((m.channel.topic.clone(), m.log_time, tick, q0));
    }
    Ok(v)
}

#[test]
fn every_form_of_the_official_writer_reads_back() {
    let files = write_with_python("recording-official-writer", 400);
    for form in ["zstd", "lz4", "none", "unchunked"] {
        let f = &files[form];
        let bytes = std::fs::read(f["path"].as_str().expect("path")).expect("read file");
        let got = read_all(&bytes).unwrap_or_else(|e| panic!("{form}: {e:?}"));
        let want = f["messages"].as_array().expect("messages");
        assert_eq!(got.len(), want.len(), "{form}: message count");
        for (g, w) in got.iter().zip(want) {
            assert_eq!(g.0, w["topic"].as_str().expect("topic"), "{form}");
            assert_eq!(g.1, w["log_time"].as_u64().expect("log time"), "{form}");
            assert_eq!(g.2, w["tick"].as_u64().unwrap_or(0), "{form}");
            let q0 = w["q0"].as_f64().expect("q0");
            assert!((f64::from(g.3) - q0).abs() < 1e-6, "{form}: q0 {} vs {q0}", g.3);
        }
    }
    // The compressed forms are what they claim: zstd and lz4 much smaller than the uncompressed chunks.
    let size = |form: &str| std::fs::metadata(files[form]["path"].as_str().expect("path")).expect("stat").len();
    assert!(size("zstd") * 3 < size("none") && size("lz4") * 2 < size("none"));
}

#[test]
fn truncated_or_corrupt_compressed_files_give_typed_errors() {
    let files = write_with_python("recording-official-writer-corrupt", 100);
    for form in ["zstd", "lz4", "none", "unchunked"] {
        let bytes = std::fs::read(files[form]["path"].as_str().expect("path")).expect("read file");
        let n = files[form]["messages"].as_array().map_or(0, Vec::len);
        // Cut anywhere: never a panic, never more messages than written, always an error (the footer is gone).
        for k in 1..40 {
            let cut = bytes.len() * k / 40;
            match read_all(&bytes[..cut]) {
                Ok(v) => panic!("{form} cut at {cut} of {}: read {} messages without an error", bytes.len(), v.len()),
                Err(e) => assert!(
                    matches!(e, ReadError::NotMcap(_) | ReadError::Truncated { .. } | ReadError::Corrupt { .. }),
                    "{form} cut at {cut}: {e:?}"
                ),
            }
        }
        // Bytes flipped anywhere (seeded): a typed error or, where the flip hits a field nobody checks (summary
        // section, unchecked message bytes), at most the messages written; never a panic.
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..500 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let mut b = bytes.clone();
            let at = (x as usize) % b.len();
            b[at] ^= 1 + (x >> 32) as u8 % 255;
            if let Ok(v) = read_all(&b) {
                assert!(v.len() <= n, "{form}: flip at {at} read {} of {n} messages", v.len());
            }
        }
        if !matches!(form, "zstd" | "lz4") {
            continue;
        }
        // A compression this build cannot read: named in the error.
        let tag = form.as_bytes();
        let mut b = bytes.clone();
        let mut i = 0;
        while let Some(p) = b[i..].windows(tag.len()).position(|w| w == tag) {
            b[i + p..i + p + tag.len()].copy_from_slice(&b"brot"[..tag.len()]);
            i += p + tag.len();
        }
        let e = read_all(&b).expect_err("unknown compression");
        assert!(matches!(&e, ReadError::UnsupportedCompression(c) if c.starts_with("br")), "{e:?}");
        assert!(e.to_string().contains("zstd, lz4"), "{e}");
    }
    assert!(matches!(read_all(b"not an mcap file"), Err(ReadError::NotMcap(_))));
}

/// What [`recording::write_options`] writes is what it says, checked by the official Python reader: chunks
/// compressed as asked (never the `mcap` crate's zstd default when none is asked), every message there.
#[test]
fn written_compression_is_what_the_official_reader_sees() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("recording-write-options");
    std::fs::create_dir_all(&dir).expect("dir");
    for c in recording::Compression::ALL {
        let path = dir.join(format!("{}.mcap", c.name()));
        let f = std::io::BufWriter::new(std::fs::File::create(&path).expect("create"));
        let mut w = recording::write_options("ulab test", c).create(f).expect("writer");
        let ch = recording::add_topic(&mut w, "rt/lowstate", "unitree_hg::msg::dds_::LowState_").expect("channel");
        let n = 3000u32; // 3000 x 2092 bytes: about 24 chunks of 256 KiB
        for i in 0..n {
            let s = unitree_idl::hg::LowState_ { tick: i, ..Default::default() };
            let bytes = lowlevel_codec::cdr::encode(&s, lowlevel_codec::Encoding::UNITREE);
            let t = 1_000_000 + u64::from(i) * 2_000_000;
            let hdr = mcap::records::MessageHeader { channel_id: ch, sequence: i, log_time: t, publish_time: t };
            w.write_to_known_channel(&hdr, &bytes).expect("write");
        }
        w.finish().expect("finish");
        drop(w);
        let out = Command::new(python())
            .arg(workspace().join("tests/mcap/summarize_mcap.py"))
            .arg(&path)
            .output()
            .expect("run the Python mcap reader");
        assert!(out.status.success(), "Python reader failed: {}", String::from_utf8_lossy(&out.stderr));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
        let want = match c {
            recording::Compression::None => "",
            recording::Compression::Zstd => "zstd",
            recording::Compression::Lz4 => "lz4",
        };
        assert_eq!(v["chunk_compressions"], serde_json::json!([want]), "{}: {v}", c.name());
        assert!(v["chunks"].as_u64().unwrap_or(0) > 10, "{}: {}", c.name(), v["chunks"]);
        assert_eq!(v["topics"]["rt/lowstate"]["count"].as_u64(), Some(u64::from(n)), "{}", c.name());
        // And our reader reads it back, tick by tick.
        let bytes = std::fs::read(&path).expect("read");
        let got = read_all(&bytes).expect("read back");
        assert!(got.iter().enumerate().all(|(i, g)| g.2 == i as u64), "{}", c.name());
    }
}
