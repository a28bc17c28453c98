//! Text of one `f32` as the JSON form and CSV exports print it: always available (the JSON reader, which needs
//! `serde_json` with `arbitrary_precision`, is behind the `json` feature).

/// Bit pattern of the quiet NaN that prints as plain `"NaN"`.
pub(crate) const CANONICAL_NAN: u32 = 0x7fc0_0000;

/// Text of one float: shortest round-trip decimal, or the string forms for non-finite values.
pub fn float_text(x: f32) -> String {
    if x.is_finite() {
        let mut buf = ryu::Buffer::new();
        buf.format_finite(x).to_owned()
    } else if x.is_nan() {
        if x.to_bits() == CANONICAL_NAN {
            "\"NaN\"".to_owned()
        } else {
            format!("\"NaN:{:#010x}\"", x.to_bits())
        }
    } else if x > 0.0 {
        "\"Infinity\"".to_owned()
    } else {
        "\"-Infinity\"".to_owned()
    }
}
