//! Flat, named columns of a decoded message, the CSV form of a recording (`ulab log export`): `motor_state[3].q`,
//! `imu_state.rpy[2]`, one column per primitive in IDL order. Floats are written so that they parse back exactly.

use unitree_idl::{with_message_type, Field, IdlStruct, MessageType, PrimKind, Primitive, Visitor};

fn prim_text<P: Primitive>(v: &P) -> String {
    let bits = v.to_bits();
    match P::KIND {
        PrimKind::F32 => {
            let x = f32::from_bits(bits as u32);
            if x.is_finite() {
                lowlevel_codec::text::float_text(x)
            } else if x.is_nan() {
                "NaN".to_owned()
            } else if x > 0.0 {
                "inf".to_owned()
            } else {
                "-inf".to_owned()
            }
        }
        PrimKind::Bool => (bits != 0).to_string(),
        PrimKind::I16 => (bits as u16 as i16).to_string(),
        PrimKind::I32 => (bits as u32 as i32).to_string(),
        PrimKind::I64 => (bits as i64).to_string(),
        PrimKind::U8 | PrimKind::U16 | PrimKind::U32 => bits.to_string(),
    }
}

/// Collects `(column name, value)` pairs: `motor_state[3].q`, `imu_state.rpy[2]`, ...
#[derive(Debug)]
pub struct Flatten {
    prefix: String,
    pub columns: Columns,
}

impl Flatten {
    pub fn of<T: IdlStruct>(value: &T) -> Columns {
        let mut f = Flatten { prefix: String::new(), columns: Vec::new() };
        value.walk(&mut f);
        f.columns
    }

    fn nested<S: IdlStruct>(&mut self, prefix: String, value: &S) {
        let saved = std::mem::replace(&mut self.prefix, prefix);
        value.walk(self);
        self.prefix = saved;
    }
}

impl Visitor for Flatten {
    fn primitive<P: Primitive>(&mut self, name: &'static str, value: &P) {
        self.columns.push((format!("{}{name}", self.prefix), prim_text(value)));
    }
    fn primitive_array<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        for (i, v) in items.iter().enumerate() {
            self.columns.push((array_column(&format!("{}{name}", self.prefix), i), prim_text(v)));
        }
    }
    fn structure<S: IdlStruct>(&mut self, name: &'static str, value: &S) {
        let p = format!("{}{name}.", self.prefix);
        self.nested(p, value);
    }
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        for (i, v) in items.iter().enumerate() {
            let p = format!("{}.", array_column(&format!("{}{name}", self.prefix), i));
            self.nested(p, v);
        }
    }
    fn struct_sequence<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        self.struct_array(name, items);
    }
    fn primitive_sequence<P: Primitive>(&mut self, name: &'static str, items: &[P]) {
        self.primitive_array(name, items);
    }
    /// One column; the text as it is (the CSV writer quotes it).
    fn string(&mut self, name: &'static str, value: &str) {
        self.columns.push((format!("{}{name}", self.prefix), value.to_owned()));
    }
}

/// Column of element `index` of the array at `path`: `motor_state[3]`, `imu_state.rpy[2]`.
pub fn array_column(path: &str, index: usize) -> String {
    format!("{path}[{index}]")
}

/// Column of `member` of element `index` of a struct array: `motor_cmd[3].kp`.
pub fn element_column(array: &str, index: usize, member: &str) -> String {
    format!("{}.{member}", array_column(array, index))
}

/// `(column name, value)` pairs of one message.
pub type Columns = Vec<(String, String)>;

/// Decodes a sample of `kind` and flattens it; also returns its CRC status where it has one.
pub fn decode_flat(kind: MessageType, bytes: &[u8]) -> Result<(Columns, Option<bool>), lowlevel_codec::DecodeError> {
    with_message_type!(kind, T => {
        match lowlevel_codec::decode::<T>(bytes) {
            Ok(d) => Ok((Flatten::of(&d.value), lowlevel_codec::crc::check_any(&d.value))),
            Err(e) => Err(e),
        }
    })
}

/// Column names of `kind` (from its zero value).
pub fn column_names(kind: MessageType) -> Vec<String> {
    with_message_type!(kind, T => Flatten::of(&<T as Field>::zeroed()).into_iter().map(|(n, _)| n).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_named() {
        let c = column_names(MessageType::HgLowCmd);
        assert_eq!(c[0], "mode_pr");
        assert!(c.contains(&"motor_cmd[34].kd".to_owned()));
        assert_eq!(c.last().map(String::as_str), Some("crc"));
        assert!(c.contains(&element_column("motor_cmd", 34, "kd")));
        let s = column_names(MessageType::HgLowState);
        assert!(s.contains(&array_column("imu_state.quaternion", 3)));
    }
}
