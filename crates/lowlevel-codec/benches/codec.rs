//! Codec and CRC speed, as ratios against references measured in the same run.
//!
//! `cargo bench -p lowlevel-codec --bench codec` runs criterion on every case, then prints a
//! ratio table (median of repeated timed batches) that BENCHMARKS.md records:
//! * CRC: fast (carry-less multiply) vs the bit-serial reference and vs `crc32fast` (hardware CRC-32 with
//!   carry-less multiply: the speed yardstick; a different polynomial, same bytes);
//! * decode/encode of hg LowState and LowCmd vs a memcpy of the same bytes, and vs Cyclone DDS's
//!   Python serializer on Unitree's Python classes (run as a subprocess when the venv exists);
//! * the zero-copy view of hg LowState vs the same memcpy: construction alone (full validation),
//!   construction plus what a controller reads each tick, and construction plus `to_owned`.

use criterion::{black_box, Criterion};
use lowlevel_codec::{cdr, crc, view, Encoding};
use std::time::Instant;
use unitree_idl::hg;

fn sample_state() -> hg::LowState_ {
    let mut s = hg::LowState_ { tick: 123_456, ..Default::default() };
    s.imu_state.quaternion = [0.999, 0.01, -0.02, 0.03];
    for (i, m) in s.motor_state.iter_mut().enumerate() {
        let x = i as f32;
        m.mode = 1;
        m.q = 0.1 * x;
        m.dq = -0.01 * x;
        m.tau_est = 1.5 * x;
        m.temperature = [30 + i as i16, 31];
    }
    crc::seal(&mut s);
    s
}

fn sample_cmd() -> hg::LowCmd_ {
    let mut c = hg::LowCmd_::default();
    for (i, m) in c.motor_cmd.iter_mut().take(27).enumerate() {
        m.mode = 1;
        m.q = 0.05 * i as f32;
        m.kp = 100.0;
        m.kd = 2.0;
    }
    crc::seal(&mut c);
    c
}

/// What a whole-body controller reads from each LowState: tick, IMU, and q/dq/tau_est of every motor.
// Only handed to black_box: the point is the reads that fill it.
#[allow(dead_code)]
struct ControllerInputs {
    tick: u32,
    quaternion: [f32; 4],
    gyroscope: [f32; 3],
    accelerometer: [f32; 3],
    q: [f32; hg::MOTOR_SLOTS],
    dq: [f32; hg::MOTOR_SLOTS],
    tau_est: [f32; hg::MOTOR_SLOTS],
}

/// Validates a LowState sample and reads [`ControllerInputs`] through the view.
fn controller_read(bytes: &[u8]) -> Option<ControllerInputs> {
    let v = view::<hg::LowState_>(bytes).ok()?;
    let imu = v.imu_state();
    let mut out = ControllerInputs {
        tick: v.tick(),
        quaternion: imu.quaternion(),
        gyroscope: imu.gyroscope(),
        accelerometer: imu.accelerometer(),
        q: [0.0; hg::MOTOR_SLOTS],
        dq: [0.0; hg::MOTOR_SLOTS],
        tau_est: [0.0; hg::MOTOR_SLOTS],
    };
    for (i, m) in v.motor_state().iter().enumerate() {
        out.q[i] = m.q();
        out.dq[i] = m.dq();
        out.tau_est[i] = m.tau_est();
    }
    Some(out)
}

/// The same reads from an owned struct (no decoding): what the reads alone cost.
fn controller_read_owned(s: &hg::LowState_) -> ControllerInputs {
    let mut out = ControllerInputs {
        tick: s.tick,
        quaternion: s.imu_state.quaternion,
        gyroscope: s.imu_state.gyroscope,
        accelerometer: s.imu_state.accelerometer,
        q: [0.0; hg::MOTOR_SLOTS],
        dq: [0.0; hg::MOTOR_SLOTS],
        tau_est: [0.0; hg::MOTOR_SLOTS],
    };
    for (i, m) in s.motor_state.iter().enumerate() {
        out.q[i] = m.q;
        out.dq[i] = m.dq;
        out.tau_est[i] = m.tau_est;
    }
    out
}

/// Median nanoseconds per call over 31 batches sized to ~2 ms each.
fn median_ns(mut f: impl FnMut()) -> f64 {
    let mut batch = 1u64;
    loop {
        let t = Instant::now();
        for _ in 0..batch {
            f();
        }
        if t.elapsed().as_micros() > 2000 {
            break;
        }
        batch *= 2;
    }
    let mut samples: Vec<f64> = (0..31)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..batch {
                f();
            }
            t.elapsed().as_nanos() as f64 / batch as f64
        })
        .collect();
    samples.sort_by(|a, b| a.total_cmp(b));
    samples[samples.len() / 2]
}

const PYTHON_BENCH: &str = r#"
import sys, types, timeit
sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_, LowCmd_
from unitree_sdk2py.idl.default import unitree_hg_msg_dds__LowState_, unitree_hg_msg_dds__LowCmd_
for name, make in (("LowState", unitree_hg_msg_dds__LowState_), ("LowCmd", unitree_hg_msg_dds__LowCmd_)):
    msg = make()
    data = msg.serialize()
    cls = type(msg)
    n = 2000
    enc = min(timeit.repeat(msg.serialize, number=n, repeat=5)) / n * 1e9
    dec = min(timeit.repeat(lambda: cls.deserialize(data), number=n, repeat=5)) / n * 1e9
    print(name, enc, dec)
"#;

/// Python serializer ns/op: (LowState encode, decode, LowCmd encode, decode).
fn python_reference() -> Option<[f64; 4]> {
    let python = std::env::var("ULAB_PYTHON").ok().or_else(|| {
        let p = concat!(env!("CARGO_MANIFEST_DIR"), "/../../.venv/bin/python");
        std::path::Path::new(p).exists().then(|| p.to_owned())
    })?;
    let out = std::process::Command::new(python).args(["-c", PYTHON_BENCH]).output().ok()?;
    if !out.status.success() {
        eprintln!("python reference failed: {}", String::from_utf8_lossy(&out.stderr));
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let mut v = Vec::new();
    for line in text.lines() {
        v.extend(line.split_whitespace().skip(1).filter_map(|x| x.parse::<f64>().ok()));
    }
    (v.len() == 4).then(|| [v[0], v[1], v[2], v[3]])
}

fn main() {
    let state = sample_state();
    let cmd = sample_cmd();
    let state_bytes = cdr::encode(&state, Encoding::UNITREE);
    let cmd_bytes = cdr::encode(&cmd, Encoding::UNITREE);
    let image = crc::c_image(&state);
    let words = &image[..image.len() - 4];

    let mut c = Criterion::default().configure_from_args();
    {
        let mut g = c.benchmark_group("crc_lowstate_image");
        g.bench_function("clmul_crc_fast", |b| b.iter(|| crc::crc32_words(black_box(words))));
        g.bench_function("bit_serial_reference", |b| b.iter(|| crc::crc32_reference(black_box(words))));
        g.bench_function("crc32fast", |b| b.iter(|| crc32fast::hash(black_box(words))));
        // The carry-less-multiply kernel alone, on bytes already in MPEG-2 (swapped) order.
        let swapped: Vec<u8> = words.chunks_exact(4).flat_map(|w| [w[3], w[2], w[1], w[0]]).collect();
        g.bench_function("crc_fast_mpeg2_kernel_only", |b| {
            b.iter(|| crc_fast::checksum(crc_fast::CrcAlgorithm::Crc32Mpeg2, black_box(&swapped)))
        });
        g.bench_function("seal_hg_lowstate", |b| b.iter(|| crc::compute(black_box(&state))));
        g.finish();
    }
    {
        let mut g = c.benchmark_group("codec_hg");
        let mut dst = vec![0u8; state_bytes.len()];
        g.bench_function("memcpy_lowstate", |b| b.iter(|| dst.copy_from_slice(black_box(&state_bytes))));
        g.bench_function("decode_lowstate", |b| b.iter(|| cdr::decode::<hg::LowState_>(black_box(&state_bytes))));
        g.bench_function("view_lowstate", |b| b.iter(|| view::<hg::LowState_>(black_box(&state_bytes)).is_ok()));
        g.bench_function("view_lowstate_controller_read", |b| b.iter(|| controller_read(black_box(&state_bytes))));
        g.bench_function("view_lowstate_to_owned", |b| {
            b.iter(|| view::<hg::LowState_>(black_box(&state_bytes)).map(|v| v.to_owned()))
        });
        g.bench_function("encode_lowstate", |b| b.iter(|| cdr::encode(black_box(&state), Encoding::UNITREE)));
        g.bench_function("decode_lowcmd", |b| b.iter(|| cdr::decode::<hg::LowCmd_>(black_box(&cmd_bytes))));
        g.bench_function("encode_lowcmd", |b| b.iter(|| cdr::encode(black_box(&cmd), Encoding::UNITREE)));
        g.finish();
    }
    c.final_summary();

    // Ratio table, all measured now.
    let mut dst = vec![0u8; state_bytes.len()];
    let mut dst_cmd = vec![0u8; cmd_bytes.len()];
    let crc_fast = median_ns(|| {
        black_box(crc::crc32_words(black_box(words)));
    });
    let crc_ref = median_ns(|| {
        black_box(crc::crc32_reference(black_box(words)));
    });
    let crc_hw = median_ns(|| {
        black_box(crc32fast::hash(black_box(words)));
    });
    // What `seal`/`verify` hash: the image builder writes every word already swapped (a store in another
    // byte order, no extra pass), so only the kernel runs on it.
    let swapped_image: Vec<u8> = words.chunks_exact(4).flat_map(|w| [w[3], w[2], w[1], w[0]]).collect();
    let crc_sealed = median_ns(|| {
        black_box(crc_fast::checksum(crc_fast::CrcAlgorithm::Crc32Mpeg2, black_box(&swapped_image)));
    });
    let memcpy_state = median_ns(|| dst.copy_from_slice(black_box(&state_bytes)));
    let memcpy_cmd = median_ns(|| dst_cmd.copy_from_slice(black_box(&cmd_bytes)));
    let dec_state = median_ns(|| {
        let _ = black_box(cdr::decode::<hg::LowState_>(black_box(&state_bytes)));
    });
    let view_state = median_ns(|| {
        black_box(view::<hg::LowState_>(black_box(&state_bytes)).is_ok());
    });
    let view_read_state = median_ns(|| {
        black_box(controller_read(black_box(&state_bytes)));
    });
    let owned_read_state = median_ns(|| {
        black_box(controller_read_owned(black_box(&state)));
    });
    let view_owned_state = median_ns(|| {
        let _ = black_box(view::<hg::LowState_>(black_box(&state_bytes)).map(|v| v.to_owned()));
    });
    let enc_state = median_ns(|| {
        black_box(cdr::encode(black_box(&state), Encoding::UNITREE));
    });
    let dec_cmd = median_ns(|| {
        let _ = black_box(cdr::decode::<hg::LowCmd_>(black_box(&cmd_bytes)));
    });
    let enc_cmd = median_ns(|| {
        black_box(cdr::encode(black_box(&cmd), Encoding::UNITREE));
    });
    let gbps = |ns: f64| words.len() as f64 / ns;
    println!(
        "\n## ratio summary (median ns per call; {} B CRC image, {} B LowState, {} B LowCmd)",
        words.len(),
        state_bytes.len(),
        cmd_bytes.len()
    );
    println!("| measure | ns | ratio | target |");
    println!("|---|---:|---:|---|");
    println!("| CRC fast (clmul via crc-fast, word swap), {:.2} GB/s | {crc_fast:.0} | {:.1}x faster than bit-serial | >= 20x |", gbps(crc_fast), crc_ref / crc_fast);
    println!("| CRC as seal/verify run it (kernel on the word-swapped image), {:.2} GB/s | {crc_sealed:.0} | {:.2}x crc32fast, {:.0}x bit-serial | >= 0.5x, >= 20x |", gbps(crc_sealed), crc_hw / crc_sealed, crc_ref / crc_sealed);
    println!("| CRC bit-serial reference, {:.2} GB/s | {crc_ref:.0} | 1 | |", gbps(crc_ref));
    println!(
        "| crc32fast (hardware yardstick), {:.2} GB/s | {crc_hw:.0} | ours = {:.2}x its speed | >= 0.5x |",
        gbps(crc_hw),
        crc_hw / crc_fast
    );
    println!("| memcpy hg LowState | {memcpy_state:.0} | 1 | |");
    println!("| decode hg LowState | {dec_state:.0} | {:.1}x memcpy | <= 4x |", dec_state / memcpy_state);
    println!(
        "| view hg LowState (construct = full validation) | {view_state:.1} | {:.2}x memcpy | <= 4x |",
        view_state / memcpy_state
    );
    println!("| view hg LowState + controller read (tick, IMU quat/gyro/accel, q/dq/tau_est x 35) | {view_read_state:.0} | {:.1}x memcpy | |", view_read_state / memcpy_state);
    println!("| (reference: the same reads from an owned hg::LowState_, no decoding) | {owned_read_state:.0} | {:.1}x memcpy | |", owned_read_state / memcpy_state);
    println!(
        "| view hg LowState + to_owned | {view_owned_state:.0} | {:.1}x memcpy | |",
        view_owned_state / memcpy_state
    );
    println!("| encode hg LowState | {enc_state:.0} | {:.1}x memcpy | |", enc_state / memcpy_state);
    println!("| memcpy hg LowCmd | {memcpy_cmd:.0} | 1 | |");
    println!("| decode hg LowCmd | {dec_cmd:.0} | {:.1}x memcpy | |", dec_cmd / memcpy_cmd);
    println!("| encode hg LowCmd | {enc_cmd:.0} | {:.1}x memcpy | |", enc_cmd / memcpy_cmd);
    match python_reference() {
        Some([py_enc_s, py_dec_s, py_enc_c, py_dec_c]) => {
            println!(
                "| Python cyclonedds encode hg LowState | {py_enc_s:.0} | ours {:.0}x faster | |",
                py_enc_s / enc_state
            );
            println!(
                "| Python cyclonedds decode hg LowState | {py_dec_s:.0} | ours {:.0}x faster | |",
                py_dec_s / dec_state
            );
            println!(
                "| Python cyclonedds encode hg LowCmd | {py_enc_c:.0} | ours {:.0}x faster | |",
                py_enc_c / enc_cmd
            );
            println!(
                "| Python cyclonedds decode hg LowCmd | {py_dec_c:.0} | ours {:.0}x faster | |",
                py_dec_c / dec_cmd
            );
        }
        None => println!("| Python cyclonedds | n/a | venv not found (run scripts/setup.sh) | |"),
    }
}
