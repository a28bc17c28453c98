//! Unitree's CRC: CRC-32 with polynomial 0x04C11DB7, seed 0xFFFFFFFF, no reflection and no final
//! xor, fed 32-bit little-endian words most-significant bit first, over the **C struct image** of
//! the message (natural alignment, padding zeroed) without its trailing `crc` word.
//!
//! Unitree's C++ SDK hashes the padding bytes as they happen to lie in memory; we always zero
//! them, which is what a freshly value-initialised C++ message also has.
//!
//! [`crc32_words`] is the fast one (carry-less multiply via `crc-fast`); [`crc32_reference`] is
//! the bit-serial definition, kept to test it against.

use unitree_idl::{align_up, go, hg, Field, IdlStruct, Primitive, Visitor};

const POLY: u32 = 0x04C1_1DB7;
const SEED: u32 = 0xFFFF_FFFF;

/// CRC by definition: one bit at a time, each word from its most significant bit.
/// `image` is read as little-endian words; a trailing partial word is ignored, as the SDK does.
pub fn crc32_reference(image: &[u8]) -> u32 {
    let mut crc = SEED;
    for word in image.chunks_exact(4) {
        let data = u32::from_le_bytes([word[0], word[1], word[2], word[3]]);
        for bit in (0..32).rev() {
            let feedback = (crc >> 31) ^ ((data >> bit) & 1);
            crc <<= 1;
            if feedback != 0 {
                crc ^= POLY;
            }
        }
    }
    crc
}

/// Fast CRC over whole little-endian words: Unitree's CRC is CRC-32/MPEG-2 of the image with
/// each word byte-swapped, so the words are swapped in a small stack buffer and streamed through
/// `crc-fast` (carry-less multiply folding on x86_64/aarch64, tables elsewhere).
/// Equal to [`crc32_reference`] for every input (a trailing partial word is ignored).
pub fn crc32_words(image: &[u8]) -> u32 {
    use std::cell::RefCell;
    thread_local! {
        // Scratch for the swapped words, reused so that no call pays for zeroing a buffer.
        static SWAPPED: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
    }
    let whole = image.len() & !3;
    SWAPPED.with(|cell| match cell.try_borrow_mut() {
        Ok(mut buf) => {
            if buf.len() < whole {
                buf.resize(whole, 0);
            }
            swap_words(&image[..whole], &mut buf[..whole]);
            crc_fast::checksum(crc_fast::CrcAlgorithm::Crc32Mpeg2, &buf[..whole]) as u32
        }
        // Re-entered on this thread (cannot happen today): fall back to a fresh buffer.
        Err(_) => {
            let mut buf = vec![0u8; whole];
            swap_words(&image[..whole], &mut buf);
            crc_fast::checksum(crc_fast::CrcAlgorithm::Crc32Mpeg2, &buf) as u32
        }
    })
}

/// Byte-swaps every 32-bit word of `src` into `dst` (same length, a multiple of 4), two words at
/// a time with shifts and masks, which the compiler vectorises.
#[inline]
fn swap_words(src: &[u8], dst: &mut [u8]) {
    let mut d8 = dst.chunks_exact_mut(8);
    let mut s8 = src.chunks_exact(8);
    for (d, s) in (&mut d8).zip(&mut s8) {
        let mut b = [0u8; 8];
        b.copy_from_slice(s);
        let w = u64::from_le_bytes(b);
        let w = ((w & 0x00ff_00ff_00ff_00ff) << 8) | ((w >> 8) & 0x00ff_00ff_00ff_00ff);
        let w = ((w & 0x0000_ffff_0000_ffff) << 16) | ((w >> 16) & 0x0000_ffff_0000_ffff);
        d.copy_from_slice(&w.to_le_bytes());
    }
    for (d, s) in d8.into_remainder().chunks_exact_mut(4).zip(s8.remainder().chunks_exact(4)) {
        d.copy_from_slice(&[s[3], s[2], s[1], s[0]]);
    }
}

/// The C struct image of `value`: members at their natural alignment, structs padded to their
/// alignment, padding zeroed, little-endian (the robot's byte order).
///
/// Sequences and strings have no flat image (they are `std::vector` / `std::string` in C++) and
/// are skipped; no type that carries a CRC contains one.
pub fn c_image<T: IdlStruct>(value: &T) -> Vec<u8> {
    image_with::<T, false>(value)
}

/// The C struct image with every 32-bit word byte-swapped: the byte order in which Unitree's CRC
/// reads it, so the CRC is plain CRC-32/MPEG-2 of these bytes with no extra pass.
fn c_image_word_swapped<T: IdlStruct>(value: &T) -> Vec<u8> {
    image_with::<T, true>(value)
}

fn image_with<T: IdlStruct, const SWAP: bool>(value: &T) -> Vec<u8> {
    // Zeroed up front: padding is whatever is not written.
    let mut writer = CImage::<SWAP> { out: vec![0; T::C_SIZE], pos: 0 };
    value.walk(&mut writer);
    writer.out
}

/// Writes members at their C offsets; with `SWAP`, byte `i` goes to `i ^ 3` (its mirror within
/// its 32-bit word), which turns every aligned word into its big-endian form.
struct CImage<const SWAP: bool> {
    out: Vec<u8>,
    pos: usize,
}

impl<const SWAP: bool> CImage<SWAP> {
    #[inline(always)]
    fn pad_to(&mut self, align: usize) {
        self.pos = align_up(self.pos, align);
    }
    #[inline(always)]
    fn put<P: Primitive>(&mut self, value: P) {
        let bytes = value.to_bits().to_le_bytes();
        // Offsets come from the type's own layout, which C_SIZE was computed from.
        if SWAP {
            for (k, b) in bytes[..P::SIZE].iter().enumerate() {
                if let Some(dst) = self.out.get_mut((self.pos + k) ^ 3) {
                    *dst = *b;
                }
            }
        } else if let Some(dst) = self.out.get_mut(self.pos..self.pos + P::SIZE) {
            dst.copy_from_slice(&bytes[..P::SIZE]);
        }
        self.pos += P::SIZE;
    }
}

impl<const SWAP: bool> Visitor for CImage<SWAP> {
    #[inline(always)]
    fn primitive<P: Primitive>(&mut self, _name: &'static str, value: &P) {
        self.pad_to(P::SIZE);
        self.put(*value);
    }
    #[inline(always)]
    fn primitive_array<P: Primitive>(&mut self, _name: &'static str, items: &[P]) {
        self.pad_to(P::SIZE);
        items.iter().for_each(|item| self.put(*item));
    }
    #[inline(always)]
    fn structure<S: IdlStruct>(&mut self, _name: &'static str, value: &S) {
        self.pad_to(S::C_ALIGN);
        value.walk(self);
        self.pad_to(S::C_ALIGN);
    }
    #[inline(always)]
    fn struct_array<S: IdlStruct>(&mut self, name: &'static str, items: &[S]) {
        items.iter().for_each(|item| self.structure(name, item));
    }
    fn struct_sequence<S: IdlStruct>(&mut self, _name: &'static str, _items: &[S]) {}
    fn primitive_sequence<P: Primitive>(&mut self, _name: &'static str, _items: &[P]) {}
    fn string(&mut self, _name: &'static str, _value: &str) {}
}

/// A message whose last member is Unitree's CRC of everything before it (hg/go `LowCmd_` and `LowState_`). Implemented
/// here for those four types only.
pub trait Checksummed: IdlStruct {
    /// The stored `crc` member.
    fn crc(&self) -> u32;
    /// The `crc` member, to be overwritten ([`seal`] writes the computed value here).
    fn crc_mut(&mut self) -> &mut u32;
}

macro_rules! sealed {
    ($($t:ty),*) => {$(
        impl Checksummed for $t {
            fn crc(&self) -> u32 { self.crc }
            fn crc_mut(&mut self) -> &mut u32 { &mut self.crc }
        }
        // The crc must be the image's last word for "all words but the last" to be right.
        const _: () = assert!(<$t as Field>::C_SIZE % 4 == 0 && <$t as Field>::C_ALIGN == 4);
    )*};
}
sealed!(hg::LowCmd_, hg::LowState_, go::LowCmd_, go::LowState_);

/// Unitree's CRC of `value` (its stored `crc` is not part of the input).
pub fn compute<T: Checksummed>(value: &T) -> u32 {
    let image = c_image_word_swapped(value);
    crc_fast::checksum(crc_fast::CrcAlgorithm::Crc32Mpeg2, &image[..image.len() - 4]) as u32
}

/// Sets the `crc` member so that the message verifies.
pub fn seal<T: Checksummed>(value: &mut T) {
    let crc = compute(value);
    *value.crc_mut() = crc;
}

/// Whether the stored `crc` member matches the message.
pub fn verify<T: Checksummed>(value: &T) -> bool {
    compute(value) == value.crc()
}

/// `(computed, stored)` CRC of a message of any type, `None` for the types without a CRC.
fn sealed_pair<T: IdlStruct>(value: &T) -> Option<(u32, u32)> {
    fn pair<S: Checksummed>(v: &S) -> (u32, u32) {
        (compute(v), v.crc())
    }
    let any = value as &dyn core::any::Any;
    any.downcast_ref::<hg::LowCmd_>()
        .map(pair)
        .or_else(|| any.downcast_ref::<hg::LowState_>().map(pair))
        .or_else(|| any.downcast_ref::<go::LowCmd_>().map(pair))
        .or_else(|| any.downcast_ref::<go::LowState_>().map(pair))
}

/// CRC status of any message type: `Some(ok)` for the four types that carry a CRC, else `None`.
pub fn check_any<T: IdlStruct>(value: &T) -> Option<bool> {
    sealed_pair(value).map(|(computed, stored)| computed == stored)
}

/// CRC of any message type that carries one, `None` for the others.
pub fn compute_any<T: IdlStruct>(value: &T) -> Option<u32> {
    sealed_pair(value).map(|(computed, _)| computed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Image sizes and word counts as stated for Unitree's SDK (reference sheet).
    #[test]
    fn image_sizes_match_the_sdk() {
        assert_eq!(c_image(&hg::LowCmd_::default()).len(), 1004);
        assert_eq!(c_image(&hg::LowState_::default()).len(), 2092);
        assert_eq!(c_image(&go::LowCmd_::default()).len(), 812);
        assert_eq!(c_image(&go::LowState_::default()).len(), 1180);
    }

    /// The swapped image is the LE image with each word reversed, and `compute` (which hashes it
    /// directly) agrees with the reference over the LE image.
    #[test]
    fn word_swapped_image_and_compute_agree_with_reference() {
        let mut state = hg::LowState_ { tick: 0x0102_0304, ..Default::default() };
        state.motor_state[3].temperature = [-2, 0x1234];
        state.imu_state.temperature = -300;
        state.motor_state[34].mode = 0xAB;
        let le = c_image(&state);
        let swapped = c_image_word_swapped(&state);
        let expected: Vec<u8> = le.chunks_exact(4).flat_map(|w| [w[3], w[2], w[1], w[0]]).collect();
        assert_eq!(swapped, expected);
        assert_eq!(compute(&state), crc32_reference(&le[..le.len() - 4]));
    }

    /// CRC of all-zero messages, as published for Unitree's implementation.
    #[test]
    fn zero_images_match_published_crcs() {
        assert_eq!(compute(&hg::LowCmd_::default()), 0xFE17_2F9F);
        assert_eq!(compute(&hg::LowState_::default()), 0xD64B_B04A);
        assert_eq!(compute(&go::LowCmd_::default()), 0x4B5A_4880);
        assert_eq!(compute(&go::LowState_::default()), 0x85F1_1EA6);
    }

    /// The reference equals CRC-32/MPEG-2 of the byte-swapped words (its check value is
    /// 0x0376E6E7 over "123456789"), an independent statement of the same function.
    #[test]
    fn reference_is_mpeg2_on_swapped_words() {
        fn mpeg2(bytes: &[u8]) -> u32 {
            let mut crc = 0xFFFF_FFFFu32;
            for &byte in bytes {
                crc ^= u32::from(byte) << 24;
                for _ in 0..8 {
                    crc = if crc & 0x8000_0000 != 0 { (crc << 1) ^ 0x04C1_1DB7 } else { crc << 1 };
                }
            }
            crc
        }
        // The catalogue's check value pins the byte-wise MPEG-2 definition...
        assert_eq!(mpeg2(b"123456789"), 0x0376_E6E7);
        // ...which, on "12345678" fed as byte-swapped words, must equal Unitree's word CRC.
        let image = [b'4', b'3', b'2', b'1', b'8', b'7', b'6', b'5'];
        assert_eq!(crc32_reference(&image), mpeg2(b"12345678"));
        assert_eq!(crc32_words(&image), mpeg2(b"12345678"));
    }
}
