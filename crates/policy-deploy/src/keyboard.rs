//! Keyboard control of the velocity command (`ulab deploy --keyboard`): what each key does, with no terminal I/O
//! here (the CLI reads the keys), so that the mapping is tested without a terminal.
//!
//! | key | effect |
//! |---|---|
//! | `w` / ↑, `s` / ↓ | forward speed vx ± [`STEP`] m/s |
//! | `a`, `d` | sideways speed vy ± [`STEP`] m/s (left positive) |
//! | `q` / ←, `e` / → | yaw rate wz ± [`STEP`] rad/s (left, counter-clockwise, positive) |
//! | space, `x`, `0` | stand: every component 0 |
//! | Esc, Ctrl-C | stop: damping, then exit (a raw terminal does not turn Ctrl-C into a signal) |
//!
//! Each component is clamped to [`LIMIT`], the command ranges the shipped policies were trained on.

/// A key press, as the CLI decodes it from the terminal (or from a byte of a piped stdin).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Key {
    Char(char),
    Up,
    Down,
    Left,
    Right,
    Esc,
    CtrlC,
}

impl Key {
    /// The key a byte of a non-terminal stdin stands for (ETX is Ctrl-C, ESC is Esc).
    pub fn from_byte(b: u8) -> Key {
        match b {
            0x03 => Key::CtrlC,
            0x1b => Key::Esc,
            _ => Key::Char(char::from(b)),
        }
    }
}

/// What a key does to the deployment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KeyEffect {
    /// The new velocity command `(vx, vy, wz)`.
    Command([f64; 3]),
    /// Stop the policy (damping, then exit).
    Stop,
    /// Not a control key.
    Ignored,
}

/// Change per key press of vx (m/s), vy (m/s) and wz (rad/s).
pub const STEP: f64 = 1.0 / PRESSES_PER_UNIT;
const PRESSES_PER_UNIT: f64 = 10.0;
/// Largest magnitude of vx, vy and wz: the command ranges of unitree_rl_gym's H1-2 training (±1 m/s forward,
/// ±0.5 m/s sideways here, narrower than its ±1 because the shipped policies track sideways commands worst).
pub const LIMIT: [f64; 3] = [1.0, 0.5, 1.0];

/// The effect of `key` on the current command.
pub fn apply(key: Key, command: [f64; 3]) -> KeyEffect {
    let (axis, sign) = match key {
        Key::Esc | Key::CtrlC => return KeyEffect::Stop,
        Key::Char(' ' | 'x' | 'X' | '0') => return KeyEffect::Command([0.0; 3]),
        Key::Char('w' | 'W') | Key::Up => (0, 1.0),
        Key::Char('s' | 'S') | Key::Down => (0, -1.0),
        Key::Char('a' | 'A') => (1, 1.0),
        Key::Char('d' | 'D') => (1, -1.0),
        Key::Char('q' | 'Q') | Key::Left => (2, 1.0),
        Key::Char('e' | 'E') | Key::Right => (2, -1.0),
        Key::Char(_) => return KeyEffect::Ignored,
    };
    let mut next = command;
    // Counted in steps and divided once, so that repeated presses land on the nearest double of each multiple
    // (three additions of 0.1 give 0.30000000000000004, 3 / 10 gives 0.3).
    next[axis] = ((next[axis] * PRESSES_PER_UNIT).round() + sign) / PRESSES_PER_UNIT;
    next[axis] = next[axis].clamp(-LIMIT[axis], LIMIT[axis]);
    KeyEffect::Command(next)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn press(keys: &str, from: [f64; 3]) -> [f64; 3] {
        keys.bytes().fold(from, |c, b| match apply(Key::from_byte(b), c) {
            KeyEffect::Command(n) => n,
            other => panic!("{b}: {other:?}"),
        })
    }

    #[test]
    fn keys_step_each_axis_and_stop_at_the_limits() {
        assert_eq!(press("www", [0.0; 3]), [0.3, 0.0, 0.0]);
        assert_eq!(press("wws", [0.0; 3]), [0.1, 0.0, 0.0]);
        assert_eq!(press("aaaaaaaaaa", [0.0; 3]), [0.0, 0.5, 0.0]);
        assert_eq!(press("ddd", [0.0; 3]), [0.0, -0.3, 0.0]);
        assert_eq!(press("q", [0.0; 3]), [0.0, 0.0, 0.1]);
        assert_eq!(press(&"e".repeat(30), [0.0; 3]), [0.0, 0.0, -1.0]);
        assert_eq!(press(&"w".repeat(30), [0.0; 3]), [1.0, 0.0, 0.0]);
        assert_eq!(press("x", [0.4, -0.2, 0.3]), [0.0; 3]);
        assert_eq!(press(" ", [0.4, -0.2, 0.3]), [0.0; 3]);
        // Arrows act like w/s/q/e.
        assert_eq!(apply(Key::Up, [0.0; 3]), KeyEffect::Command([0.1, 0.0, 0.0]));
        assert_eq!(apply(Key::Left, [0.0; 3]), KeyEffect::Command([0.0, 0.0, 0.1]));
        assert_eq!(apply(Key::Right, [0.0; 3]), KeyEffect::Command([0.0, 0.0, -0.1]));
        assert_eq!(apply(Key::Down, [0.0; 3]), KeyEffect::Command([-0.1, 0.0, 0.0]));
    }

    #[test]
    fn escape_and_ctrl_c_stop_and_other_keys_do_nothing() {
        assert_eq!(apply(Key::from_byte(0x03), [0.2; 3]), KeyEffect::Stop);
        assert_eq!(apply(Key::from_byte(0x1b), [0.2; 3]), KeyEffect::Stop);
        assert_eq!(apply(Key::Char('\n'), [0.2; 3]), KeyEffect::Ignored);
        assert_eq!(apply(Key::Char('z'), [0.2; 3]), KeyEffect::Ignored);
    }

    #[test]
    fn a_command_beyond_the_limit_is_brought_back_by_one_press() {
        // A --command of 2 m/s (allowed up to ±3) then one press: clamped to the keyboard's range.
        assert_eq!(apply(Key::Char('w'), [2.0, 0.0, 0.0]), KeyEffect::Command([1.0, 0.0, 0.0]));
    }
}
