//! Zero-copy views (`lowlevel_codec::view`):
//! * on the golden corpus (bytes from Cyclone DDS's Python serializer on Unitree's classes,
//!   values recorded in JSON by that same independent pipeline), every accessor of hg/go
//!   `LowState`/`LowCmd` and their nested views equals the recorded member, bit for bit, and
//!   `to_owned` equals the recorded value for every viewable type;
//! * for random values in all four encodings, accessors equal the fields `decode` returns;
//! * for random edits of valid samples (bytes changed, DHEADERs hit on purpose, truncation,
//!   extension, header options), `view` fails iff `decode` fails, with the same error;
//! * layouts agree with the payload sizes and offsets the golden generator checks.

use arbitrary::{Arbitrary, Unstructured};
use lowlevel_codec::view::{self, go as gv, hg as hv, Layout, StructArray, StructView, Viewable};
use lowlevel_codec::{cdr, crc, fuzzing, json, with_viewable_type, DecodeError, Encoding, Endianness, Representation};
use proptest::prelude::*;
use serde_json::Value;
use std::path::Path;
use unitree_idl::{go, hg, MessageType};

/// A view value against its recorded JSON form, bit for bit.
trait MatchesJson {
    fn matches(&self, json: &Value) -> bool;
}

macro_rules! integer_matches_json {
    ($($t:ty),*) => {$(
        impl MatchesJson for $t {
            fn matches(&self, json: &Value) -> bool {
                json.as_i64() == Some(i64::from(*self))
            }
        }
    )*};
}
integer_matches_json!(u8, i16, u16, i32, u32);

impl MatchesJson for f32 {
    fn matches(&self, json: &Value) -> bool {
        match json {
            // The recorded decimal reads back as exactly the float32 (corpus/golden/README.md).
            Value::Number(n) => n.as_f64().is_some_and(|x| (x as f32).to_bits() == self.to_bits()),
            Value::String(s) => match s.as_str() {
                "NaN" => self.to_bits() == 0x7fc0_0000,
                "Infinity" => *self == f32::INFINITY,
                "-Infinity" => *self == f32::NEG_INFINITY,
                // Our own JSON writer's form for other NaN payloads (property tests only).
                other => {
                    other.strip_prefix("NaN:0x").and_then(|h| u32::from_str_radix(h, 16).ok()) == Some(self.to_bits())
                }
            },
            _ => false,
        }
    }
}

impl<T: MatchesJson, const N: usize> MatchesJson for [T; N] {
    fn matches(&self, json: &Value) -> bool {
        json.as_array().is_some_and(|a| a.len() == N && self.iter().zip(a).all(|(x, j)| x.matches(j)))
    }
}

/// Checks the listed accessors of `$view` against the members of the JSON object `$json`, and
/// that they and the `nested` members (checked by the caller) are all the members it records.
macro_rules! check_members {
    ($errs:expr, $path:expr, $view:expr, $json:expr, [$($m:ident),* $(,)?], nested [$($n:literal),*]) => {{
        let mut checked: Vec<&str> = vec![$($n),*];
        $(
            let name = stringify!($m);
            if !$view.$m().matches(&$json[name]) {
                $errs.push(format!("{}.{name}: view {:?}, recorded {}", $path, $view.$m(), $json[name]));
            }
            checked.push(name);
        )*
        let mut recorded: Vec<&str> = $json.as_object().map(|o| o.keys().map(String::as_str).collect()).unwrap_or_default();
        checked.sort_unstable();
        recorded.sort_unstable();
        if checked != recorded {
            $errs.push(format!("{}: checked {checked:?}, recorded {recorded:?}", $path));
        }
    }};
}

type Errors = Vec<String>;

fn check_array<'a, V: StructView<'a>, const N: usize>(
    errs: &mut Errors,
    path: &str,
    array: StructArray<'a, V, N>,
    json: &Value,
    check: fn(&mut Errors, &str, V, &Value),
) {
    let Some(recorded) = json.as_array().filter(|a| a.len() == N && array.len() == N && array.iter().len() == N) else {
        errs.push(format!("{path}: expected {N} elements, recorded {json}"));
        return;
    };
    if array.get(N).is_some() {
        errs.push(format!("{path}: element {N} exists"));
    }
    for (i, (element, j)) in array.iter().zip(recorded).enumerate() {
        check(errs, &format!("{path}[{i}]"), element, j);
    }
    // `get` and `iter` agree.
    for i in 0..N {
        let canonical = |e: V| cdr::encode(&e.owned(), Encoding::UNITREE);
        if array.get(i).map(canonical) != array.iter().nth(i).map(canonical) {
            errs.push(format!("{path}[{i}]: get and iter differ"));
        }
    }
}

fn hg_imu(errs: &mut Errors, path: &str, v: hv::IMUStateView<'_>, j: &Value) {
    check_members!(errs, path, v, j, [quaternion, gyroscope, accelerometer, rpy, temperature], nested []);
}

fn hg_motor_state(errs: &mut Errors, path: &str, v: hv::MotorStateView<'_>, j: &Value) {
    check_members!(errs, path, v, j, [mode, q, dq, ddq, tau_est, temperature, vol, sensor, motorstate, reserve], nested []);
}

fn hg_motor_cmd(errs: &mut Errors, path: &str, v: hv::MotorCmdView<'_>, j: &Value) {
    check_members!(errs, path, v, j, [mode, q, dq, tau, kp, kd, reserve], nested []);
}

fn hg_low_state(errs: &mut Errors, v: hv::LowStateView<'_>, j: &Value) {
    check_members!(errs, "", v, j, [version, mode_pr, mode_machine, tick, wireless_remote, reserve, crc], nested ["imu_state", "motor_state"]);
    hg_imu(errs, "imu_state", v.imu_state(), &j["imu_state"]);
    check_array(errs, "motor_state", v.motor_state(), &j["motor_state"], hg_motor_state);
}

fn hg_low_cmd(errs: &mut Errors, v: hv::LowCmdView<'_>, j: &Value) {
    check_members!(errs, "", v, j, [mode_pr, mode_machine, reserve, crc], nested["motor_cmd"]);
    check_array(errs, "motor_cmd", v.motor_cmd(), &j["motor_cmd"], hg_motor_cmd);
}

fn go_imu(errs: &mut Errors, path: &str, v: gv::IMUStateView<'_>, j: &Value) {
    check_members!(errs, path, v, j, [quaternion, gyroscope, accelerometer, rpy, temperature], nested []);
}

fn go_motor_state(errs: &mut Errors, path: &str, v: gv::MotorStateView<'_>, j: &Value) {
    check_members!(errs, path, v, j, [mode, q, dq, ddq, tau_est, q_raw, dq_raw, ddq_raw, temperature, lost, reserve], nested []);
}

fn go_motor_cmd(errs: &mut Errors, path: &str, v: gv::MotorCmdView<'_>, j: &Value) {
    check_members!(errs, path, v, j, [mode, q, dq, tau, kp, kd, reserve], nested []);
}

fn go_low_state(errs: &mut Errors, v: gv::LowStateView<'_>, j: &Value) {
    check_members!(
        errs,
        "",
        v,
        j,
        [head, level_flag, frame_reserve, sn, version, bandwidth, foot_force, foot_force_est, tick, wireless_remote, bit_flag, adc_reel, temperature_ntc1, temperature_ntc2, power_v, power_a, fan_frequency, reserve, crc],
        nested ["imu_state", "motor_state", "bms_state"]
    );
    go_imu(errs, "imu_state", v.imu_state(), &j["imu_state"]);
    check_array(errs, "motor_state", v.motor_state(), &j["motor_state"], go_motor_state);
    let bms = v.bms_state();
    check_members!(errs, "bms_state", bms, j["bms_state"], [version_high, version_low, status, soc, current, cycle, bq_ntc, mcu_ntc, cell_vol], nested []);
}

fn go_low_cmd(errs: &mut Errors, v: gv::LowCmdView<'_>, j: &Value) {
    check_members!(
        errs,
        "",
        v,
        j,
        [head, level_flag, frame_reserve, sn, version, bandwidth, wireless_remote, led, fan, gpio, reserve, crc],
        nested ["motor_cmd", "bms_cmd"]
    );
    check_array(errs, "motor_cmd", v.motor_cmd(), &j["motor_cmd"], go_motor_cmd);
    let bms = v.bms_cmd();
    check_members!(errs, "bms_cmd", bms, j["bms_cmd"], [off, reserve], nested []);
}

/// Every accessor of the view of `bytes` against `value` (the recorded JSON member object), for
/// the four types with hand-written accessor checks; `None` for other types.
fn check_accessors(ty: MessageType, bytes: &[u8], value: &Value) -> Option<Result<(), String>> {
    let mut errs = Errors::new();
    let result = match ty {
        MessageType::HgLowState => view::view::<hg::LowState_>(bytes).map(|v| hg_low_state(&mut errs, *v, value)),
        MessageType::HgLowCmd => view::view::<hg::LowCmd_>(bytes).map(|v| hg_low_cmd(&mut errs, *v, value)),
        MessageType::GoLowState => view::view::<go::LowState_>(bytes).map(|v| go_low_state(&mut errs, *v, value)),
        MessageType::GoLowCmd => view::view::<go::LowCmd_>(bytes).map(|v| go_low_cmd(&mut errs, *v, value)),
        _ => return None,
    };
    Some(match result {
        Err(e) => Err(format!("view failed: {e}")),
        Ok(()) if errs.is_empty() => Ok(()),
        Ok(()) => Err(errs.join("\n")),
    })
}

/// The view of a valid sample: header as recorded, `to_owned` equal to `expected`, CRC
/// verdict as recorded (`None` for types without a CRC).
fn check_owned<T: Viewable>(
    bytes: &[u8],
    expected: &T,
    encoding: Encoding,
    crc_ok: Option<bool>,
) -> Result<(), String> {
    let v = view::view::<T>(bytes).map_err(|e| format!("view failed: {e}"))?;
    if v.encoding() != encoding {
        return Err(format!("header says {:?}, expected {encoding:?}", v.encoding()));
    }
    if cdr::encode(&v.to_owned(), Encoding::UNITREE) != cdr::encode(expected, Encoding::UNITREE) {
        return Err("to_owned differs from the recorded value".into());
    }
    let decoded = v.to_decoded();
    if (decoded.encoding, decoded.options) != (encoding, 0)
        || cdr::encode(&decoded.value, Encoding::UNITREE) != cdr::encode(expected, Encoding::UNITREE)
    {
        return Err("to_decoded differs".into());
    }
    if crc::check_any(&v.to_owned()) != crc_ok {
        return Err(format!("CRC verdict {:?}, recorded {crc_ok:?}", crc::check_any(&v.to_owned())));
    }
    Ok(())
}

#[test]
fn golden_corpus_views_equal_recorded_values() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../corpus/golden");
    let mut paths: Vec<_> = std::fs::read_dir(&dir).expect("corpus/golden").map(|e| e.expect("entry").path()).collect();
    paths.sort();
    let (mut owned_checked, mut accessors_checked, mut failures) = (0, 0, Vec::new());
    for path in paths {
        let cdr_path = path.with_extension("cdr");
        if path.extension().and_then(|e| e.to_str()) != Some("json") || !cdr_path.exists() {
            continue;
        }
        let name = path.file_stem().expect("stem").to_string_lossy().into_owned();
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&path).expect("read json")).expect("json");
        let bytes = std::fs::read(&cdr_path).expect("read cdr");
        let ty = MessageType::from_name(doc["type"].as_str().expect("type")).expect("known type");
        let encoding = Encoding {
            representation: doc["representation"].as_str().and_then(Representation::from_name).expect("representation"),
            endianness: doc["endianness"].as_str().and_then(Endianness::from_name).expect("endianness"),
        };
        let owned = with_viewable_type!(ty, T => {
            json::value_from_json::<T>(&doc["value"])
                .map_err(|e| e.to_string())
                .and_then(|expected| check_owned::<T>(&bytes, &expected, encoding, doc["crc_ok"].as_bool()))
        });
        if let Some(result) = owned {
            owned_checked += 1;
            if let Err(e) = result {
                failures.push(format!("{name}: {e}"));
            }
        }
        // The stored `crc` against Unitree's CRC (computed in Python by the SDK's own routine).
        let crc_ok = match ty {
            MessageType::HgLowState => view::view::<hg::LowState_>(&bytes).map(|v| v.verify_crc()).ok(),
            MessageType::HgLowCmd => view::view::<hg::LowCmd_>(&bytes).map(|v| v.verify_crc()).ok(),
            MessageType::GoLowState => view::view::<go::LowState_>(&bytes).map(|v| v.verify_crc()).ok(),
            MessageType::GoLowCmd => view::view::<go::LowCmd_>(&bytes).map(|v| v.verify_crc()).ok(),
            _ => None,
        };
        if crc_ok.is_some() && crc_ok != doc["crc_ok"].as_bool() {
            failures.push(format!("{name}: verify_crc {crc_ok:?}, recorded {}", doc["crc_ok"]));
        }
        if let Some(result) = check_accessors(ty, &bytes, &doc["value"]) {
            accessors_checked += 1;
            if let Err(e) = result {
                failures.push(format!("{name}:\n{e}"));
            }
        }
    }
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
    // 16 fixed types x 4 encodings x >= 3 profiles; the four big types: >= 4 profiles each.
    assert!(owned_checked >= 16 * 4 * 3, "only {owned_checked} golden cases viewed");
    assert!(accessors_checked >= 4 * 4 * 4, "only {accessors_checked} golden cases checked accessor by accessor");
}

/// Payload sizes and offsets that the golden generator checks against Cyclone DDS
/// (corpus/golden/README.md), and one offset entry per accessor leaf for every viewable type.
#[test]
fn layouts_match_the_golden_generator() {
    let len = |l: &Layout| l.payload_len();
    for (repr, sizes) in
        [(Representation::Xcdr1, [1000, 2088, 808, 1176]), (Representation::Xcdr2, [1008, 2096, 816, 1184])]
    {
        let got = [
            len(hg::LowCmd_::layout(repr)),
            len(hg::LowState_::layout(repr)),
            len(go::LowCmd_::layout(repr)),
            len(go::LowState_::layout(repr)),
        ];
        assert_eq!(got, sizes, "{repr:?}");
    }
    // hg LowState leaves: version, mode_pr, mode_machine, tick, 5 of imu_state, then motor_state[0]
    // (mode, q, ...): mode at 70, q at 72; hg LowCmd: mode_pr, mode_machine, motor_cmd[0].mode at 2.
    let state = hg::LowState_::layout(Representation::Xcdr1).leaf_offsets();
    assert_eq!((state[9], state[10]), (70, 72));
    // Element 1 starts 4-aligned, so 3 padding bytes follow its mode: offsets are per element.
    assert_eq!(state[10] - state[9], 2);
    assert_eq!(state[21] - state[20], 4);
    assert_eq!(hg::LowCmd_::layout(Representation::Xcdr1).leaf_offsets()[2], 2);
    for &ty in MessageType::ALL {
        for repr in [Representation::Xcdr1, Representation::Xcdr2] {
            with_viewable_type!(ty, T => {
                assert_eq!(T::layout(repr).leaf_offsets().len(), <<T as Viewable>::View<'static> as StructView<'static>>::LEAVES, "{ty} {repr:?}");
                assert_eq!(T::layout(repr).payload_len(), cdr::encoded_len(&T::default(), repr), "{ty} {repr:?}");
            });
        }
    }
}

/// Hand-picked malformed XCDR2 samples whose error depends on the decoder's order of checks.
#[test]
fn error_order_matches_decode() {
    let x2 = Encoding { representation: Representation::Xcdr2, endianness: Endianness::Little };
    let good = cdr::encode(&hg::LowState_::default(), x2);
    // motor_state's DHEADER: imu_state ends at payload 70, aligned to 72; header is 4 bytes.
    let at = 4 + 72;
    // After the 4-aligned DHEADER every element takes mode + 3 padding + 13 words = 56 bytes.
    assert_eq!(u32::from_le_bytes(good[at..at + 4].try_into().expect("4 bytes")), 35 * 56, "DHEADER position");
    let mut bad = good.clone();
    bad[at] ^= 1;
    type Expected = fn(&DecodeError) -> bool;
    let cases: Vec<(Vec<u8>, Expected)> = vec![
        (bad.clone(), |e| matches!(e, DecodeError::BadDheader { member: "motor_state", offset: 72, .. })),
        // Wrong DHEADER and a cut after the array: the DHEADER is checked first.
        (bad[..bad.len() - 1].to_vec(), |e| matches!(e, DecodeError::BadDheader { .. })),
        ([bad.as_slice(), &[0]].concat(), |e| matches!(e, DecodeError::BadDheader { .. })),
        // Cut inside the array: truncation comes first.
        (bad[..at + 100].to_vec(), |e| matches!(e, DecodeError::Truncated { .. })),
        (good[..at + 2].to_vec(), |e| {
            matches!(e, DecodeError::Truncated { member: "motor_state", offset: 72, needed: 4, available: 2 })
        }),
        ([good.as_slice(), &[0, 0]].concat(), |e| matches!(e, DecodeError::TrailingBytes { offset: 2096, count: 2 })),
        (good[..3].to_vec(), |e| matches!(e, DecodeError::MissingHeader { len: 3 })),
        ([&[0u8, 7, 0, 3][..], &good[4..]].concat(), |e| matches!(e, DecodeError::Truncated { member: "crc", .. })),
        ([&[0u8, 0x42, 0, 0][..], &good[4..]].concat(), |e| {
            matches!(e, DecodeError::UnknownRepresentation { id: 0x42 })
        }),
        ([&[0u8, 0x0a, 0, 0][..], &good[4..]].concat(), |e| matches!(e, DecodeError::UnsupportedRepresentation { .. })),
        (vec![0, 7, 0, 3, 0], |e| matches!(e, DecodeError::BadPadding { padding: 3, payload: 1 })),
    ];
    for (i, (bytes, expected)) in cases.iter().enumerate() {
        let from_view = view::view::<hg::LowState_>(bytes).expect_err("invalid sample");
        assert!(expected(&from_view), "case {i}: {from_view:?}");
        assert_eq!(Err(from_view), cdr::decode::<hg::LowState_>(bytes).map(|_| ()), "case {i}");
    }
}

/// One edit of a valid sample.
#[derive(Debug, Clone)]
enum Edit {
    /// Sets a byte; `near_start` aims at the header and the first 128 payload bytes, where
    /// every DHEADER of these types sits.
    Set {
        near_start: bool,
        at: usize,
        byte: u8,
    },
    Truncate(usize),
    Extend(Vec<u8>),
    /// Declares 0..3 bytes of padding in the header options.
    Padding(u8),
    /// Sets a byte of one of the type's DHEADERs (XCDR2; no-op in XCDR1).
    Dheader {
        which: usize,
        byte: usize,
        value: u8,
    },
}

impl Edit {
    /// Applies the edit; `dheaders` are the sample's DHEADER payload offsets.
    fn apply(&self, bytes: &mut Vec<u8>, dheaders: &[usize]) {
        match self {
            Edit::Dheader { which, byte, value } if !dheaders.is_empty() => {
                let at = 4 + dheaders[which % dheaders.len()] + byte % 4;
                if let Some(b) = bytes.get_mut(at) {
                    *b = *value;
                }
            }
            Edit::Dheader { .. } => {}
            Edit::Set { near_start, at, byte } if !bytes.is_empty() => {
                let span = if *near_start { bytes.len().min(4 + 128) } else { bytes.len() };
                bytes[at % span] = *byte;
            }
            Edit::Set { .. } => {}
            Edit::Truncate(n) => bytes.truncate(n % (bytes.len() + 1)),
            Edit::Extend(tail) => bytes.extend_from_slice(tail),
            Edit::Padding(p) if bytes.len() >= 4 => bytes[3] = (bytes[3] & !3) | (p & 3),
            Edit::Padding(_) => {}
        }
    }
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        3 => (any::<bool>(), any::<usize>(), any::<u8>()).prop_map(|(near_start, at, byte)| Edit::Set { near_start, at, byte }),
        2 => any::<usize>().prop_map(Edit::Truncate),
        1 => proptest::collection::vec(any::<u8>(), 1..8).prop_map(Edit::Extend),
        1 => any::<u8>().prop_map(Edit::Padding),
        2 => (any::<usize>(), any::<usize>(), any::<u8>()).prop_map(|(which, byte, value)| Edit::Dheader { which, byte, value }),
    ]
}

/// The types with a view (every type without a sequence).
fn viewable_types() -> Vec<MessageType> {
    MessageType::ALL.iter().copied().filter(|&t| with_viewable_type!(t, T => ()).is_some()).collect()
}

fn random_value<T: for<'a> Arbitrary<'a>>(seed: &[u8]) -> Option<T> {
    T::arbitrary(&mut Unstructured::new(seed)).ok()
}

/// Random value of `T` in every encoding: the view's accessors (the four big types) and its
/// `to_owned` equal what `decode` returns.
fn accessors_equal_decode<T: Viewable + for<'a> Arbitrary<'a>>(
    ty: MessageType,
    seed: &[u8],
) -> Result<(), TestCaseError> {
    let Some(value) = random_value::<T>(seed) else { return Ok(()) };
    for encoding in fuzzing::ENCODINGS {
        let bytes = cdr::encode(&value, encoding);
        let decoded = cdr::decode::<T>(&bytes).map_err(|e| TestCaseError::fail(format!("decode: {e}")))?;
        fuzzing::view_agrees_with_decode::<T>(&bytes);
        let fields: Value = serde_json::from_str(&json::value_to_json(&decoded.value))
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        if let Some(Err(e)) = check_accessors(ty, &bytes, &fields) {
            return Err(TestCaseError::fail(format!("{ty} {encoding:?}: {e}")));
        }
    }
    Ok(())
}

fn edited_sample<T: Viewable + for<'a> Arbitrary<'a>>(seed: &[u8], encoding: Encoding, edits: &[Edit]) {
    let Some(value) = random_value::<T>(seed) else { return };
    let mut bytes = cdr::encode(&value, encoding);
    let dheaders: Vec<usize> = T::layout(encoding.representation).dheader_offsets().collect();
    for e in edits {
        e.apply(&mut bytes, &dheaders);
    }
    fuzzing::view_agrees_with_decode::<T>(&bytes);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn view_accessors_equal_decoded_fields(seed in proptest::collection::vec(any::<u8>(), 0..4096), pick in any::<usize>()) {
        let types = viewable_types();
        let ty = types[pick % types.len()];
        with_viewable_type!(ty, T => accessors_equal_decode::<T>(ty, &seed)).unwrap_or(Ok(()))?;
        // The four big types every time.
        for ty in [MessageType::HgLowState, MessageType::HgLowCmd, MessageType::GoLowState, MessageType::GoLowCmd] {
            with_viewable_type!(ty, T => accessors_equal_decode::<T>(ty, &seed)).unwrap_or(Ok(()))?;
        }
    }

    #[test]
    fn view_fails_iff_decode_fails_with_the_same_error(
        seed in proptest::collection::vec(any::<u8>(), 0..4096),
        pick in any::<usize>(),
        encoding in 0..4usize,
        edits in proptest::collection::vec(edit(), 1..4),
    ) {
        let types = viewable_types();
        let encoding = fuzzing::ENCODINGS[encoding];
        let ty = types[pick % types.len()];
        with_viewable_type!(ty, T => edited_sample::<T>(&seed, encoding, &edits));
        // The four types with struct arrays (and so DHEADERs) every time.
        let ty = [MessageType::HgLowState, MessageType::HgLowCmd, MessageType::GoLowState, MessageType::GoLowCmd][pick % 4];
        with_viewable_type!(ty, T => edited_sample::<T>(&seed, encoding, &edits));
    }
}
