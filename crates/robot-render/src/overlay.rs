//! What is written over the picture: a caption (time, label) in a built-in 5x7 bitmap font and a progress bar.
use crate::raster::Frame;

/// Glyph of a character: 7 rows of 5 pixels, bit 4 the leftmost. Lower case is drawn as upper case; a character
/// without a glyph as `?`.
fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        ' ' => [0; 7],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        ',' => [0, 0, 0, 0, 0x0C, 0x04, 0x08],
        ':' => [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '_' => [0, 0, 0, 0, 0, 0, 0x1F],
        '=' => [0, 0, 0x1F, 0, 0x1F, 0, 0],
        '+' => [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
        '/' => [0, 0x01, 0x02, 0x04, 0x08, 0x10, 0],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '[' => [0x0E, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0E],
        ']' => [0x0E, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0E],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        _ => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04],
    }
}

/// Advance of one character in font pixels (5 wide, 1 apart).
const ADVANCE: u32 = 6;
const TEXT: [u8; 3] = [245, 245, 245];
const BAR: [u8; 3] = [90, 160, 255];

/// Darkens a rectangle (a backdrop the text reads on, whatever is behind it).
fn dim(frame: &mut Frame, x0: u32, y0: u32, w: u32, h: u32) {
    let (fw, fh) = (frame.width(), frame.height());
    for y in y0..(y0 + h).min(fh) {
        for x in x0..(x0 + w).min(fw) {
            let i = (y * fw + x) as usize;
            let c = frame.get(i);
            frame.set(i, c.map(|v| (u16::from(v) * 2 / 5) as u8));
        }
    }
}

fn fill(frame: &mut Frame, x0: u32, y0: u32, w: u32, h: u32, c: [u8; 3]) {
    let (fw, fh) = (frame.width(), frame.height());
    for y in y0..(y0 + h).min(fh) {
        for x in x0..(x0 + w).min(fw) {
            frame.set((y * fw + x) as usize, c);
        }
    }
}

/// Writes `text` with its top-left corner at `(x, y)`, each font pixel `scale` x `scale` image pixels.
fn text(frame: &mut Frame, x: u32, y: u32, scale: u32, s: &str) {
    for (k, ch) in s.chars().enumerate() {
        let gx = x + k as u32 * ADVANCE * scale;
        for (row, bits) in glyph(ch).iter().enumerate() {
            for col in 0..5 {
                if bits & (0x10 >> col) != 0 {
                    fill(frame, gx + col * scale, y + row as u32 * scale, scale, scale, TEXT);
                }
            }
        }
    }
}

/// The caption lines at the top left, one under the other, and, when `progress` is given (0 to 1), a bar along
/// the bottom.
pub(crate) fn draw(frame: &mut Frame, lines: &[&str], progress: Option<f64>) {
    let scale = (frame.height() / 180).max(1);
    let margin = 4 * scale;
    let pad = 2 * scale;
    let line_h = 7 * scale + 2 * pad;
    let mut y = margin;
    for line in lines.iter().filter(|l| !l.is_empty()) {
        let n = line.chars().count() as u32;
        dim(frame, margin, y, n * ADVANCE * scale + 2 * pad - scale, line_h);
        text(frame, margin + pad, y + pad, scale, line);
        y += line_h;
    }
    if let Some(p) = progress {
        let p = if p.is_finite() { p.clamp(0.0, 1.0) } else { 0.0 };
        let h = 3 * scale;
        let w = frame.width().saturating_sub(2 * margin);
        let y = frame.height().saturating_sub(margin + h);
        dim(frame, margin, y, w, h);
        fill(frame, margin, y, (f64::from(w) * p).round() as u32, h, BAR);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glyphs_are_distinct_and_caption_and_bar_are_drawn() {
        let chars: Vec<char> = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ .,:-_=+/()[]%".chars().collect();
        for (i, a) in chars.iter().enumerate() {
            for b in &chars[i + 1..] {
                assert_ne!(glyph(*a), glyph(*b), "{a} and {b} look alike");
            }
        }
        assert_eq!(glyph('m'), glyph('M'));
        let mut f = Frame::new(320, 180);
        draw(&mut f, &["T = 1.00 S", "", "D = 2"], Some(0.5));
        let lit = |f: &Frame, y0: u32, y1: u32, x0: u32, x1: u32| {
            (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| f.pixel(x, y) == Some(TEXT)).count()
        };
        assert!(lit(&f, 0, 20, 0, 100) > 40, "the caption is written at the top left");
        // The empty line takes no room: the third line comes right under the first.
        assert!(lit(&f, 20, 31, 0, 100) > 10, "the second caption line is under the first");
        assert_eq!(lit(&f, 31, 60, 0, 320), 0, "nothing further down");
        // Half the bar is filled: its colour up to the middle, not beyond.
        let row = 180 - 4 - 1;
        assert_eq!(f.pixel(100, row), Some(BAR));
        assert_ne!(f.pixel(220, row), Some(BAR));
    }
}
