//! The robot log the diagnosis reads: hg LowCmd on `rt/lowcmd` and hg LowState on `rt/lowstate`, from an MCAP
//! in the `recording` crate's format (what `ulab record` writes) or from the CSV `ulab log export` writes
//! (columns named by `recording::columns`, documented in [`CSV_COLUMNS_DOC`]). Generated logs (bench, tests) are written in exactly the
//! same MCAP form, so real and generated logs go through one reader.
use crate::GapError;
use lowlevel_codec::cdr::{Encoding, Endianness, Representation};
use recording::columns::{array_column, element_column};
use robot_model::RobotModel;
use std::io::Write;
use unitree_idl::hg::{LowCmd_, LowState_};

/// DDS topic of commands.
pub const LOWCMD_TOPIC: &str = unitree_idl::topics::LOWCMD;
/// DDS topic of states.
pub const LOWSTATE_TOPIC: &str = unitree_idl::topics::LOWSTATE;

/// One LowCmd, joints in model (slot) order. Motors in mode 0 are stored with zero gains and torque.
#[derive(Debug, Clone, PartialEq)]
pub struct Command {
    /// Seconds since the first message of the log.
    pub t: f64,
    pub q: Vec<f64>,
    pub dq: Vec<f64>,
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
    pub tau: Vec<f64>,
}

/// One LowState, joints in model order; IMU on the torso as the robot reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub t: f64,
    pub q: Vec<f64>,
    pub dq: Vec<f64>,
    /// Motor torque estimate (`tau_est`).
    pub tau: Vec<f64>,
    /// `[w, x, y, z]`.
    pub quat: [f64; 4],
    pub gyro: [f64; 3],
    pub acc: [f64; 3],
}

/// A log: commands and measurements, each sorted by time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RobotLog {
    pub commands: Vec<Command>,
    pub states: Vec<Measurement>,
}

/// The CSV form: the two files `ulab log export` writes for a recording, one row per message.
pub const CSV_COLUMNS_DOC: &str =
    "rt_lowcmd.csv: `log_time_ns` and, per motor slot S, `motor_cmd[S].mode|q|dq|tau|kp|kd`; \
rt_lowstate.csv: `log_time_ns`, per slot `motor_state[S].q|dq|tau_est`, `imu_state.quaternion[0..4]` (w, x, y, z), \
`imu_state.gyroscope[0..3]`, `imu_state.accelerometer[0..3]`. Other columns are ignored.";

impl RobotLog {
    /// Duration between the first and last state (s).
    pub fn duration(&self) -> f64 {
        match (self.states.first(), self.states.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        }
    }

    /// Index of the latest command at or before `t` (None before the first command).
    pub fn command_at(&self, t: f64) -> Option<usize> {
        let n = self.commands.partition_point(|c| c.t <= t);
        n.checked_sub(1)
    }

    /// Checks sizes and finiteness, so the diagnosis can index without further checks.
    pub fn validate(&self, nj: usize) -> Result<(), GapError> {
        if self.states.len() < 10 || self.commands.is_empty() {
            return Err(GapError::Log(format!(
                "the log needs commands on {LOWCMD_TOPIC} and states on {LOWSTATE_TOPIC} (found {} commands, {} states)",
                self.commands.len(),
                self.states.len()
            )));
        }
        for c in &self.commands {
            let v = [&c.q, &c.dq, &c.kp, &c.kd, &c.tau];
            if v.iter().any(|x| x.len() != nj) || v.iter().any(|x| x.iter().any(|y| !y.is_finite())) || !c.t.is_finite()
            {
                return Err(GapError::Log(format!("command at t = {} has wrong sizes or non-finite values", c.t)));
            }
        }
        for s in &self.states {
            let v = [&s.q, &s.dq, &s.tau];
            let finite = v.iter().all(|x| x.iter().all(|y| y.is_finite()))
                && s.quat.iter().chain(&s.gyro).chain(&s.acc).all(|y| y.is_finite())
                && s.t.is_finite();
            if v.iter().any(|x| x.len() != nj) || !finite {
                return Err(GapError::Log(format!("state at t = {} has wrong sizes or non-finite values", s.t)));
            }
        }
        Ok(())
    }

    /// Reads an MCAP as written by `ulab record`. Other topics are ignored; undecodable messages are errors.
    pub fn from_mcap(bytes: &[u8], model: &RobotModel) -> Result<Self, GapError> {
        let mut log = RobotLog::default();
        let mut t0: Option<u64> = None;
        let stream = recording::messages(bytes)?;
        let mut raw: Vec<(u64, bool, Vec<u8>)> = Vec::new();
        for m in stream {
            let m = m?;
            let is_cmd = match m.channel.topic.as_str() {
                LOWCMD_TOPIC => true,
                LOWSTATE_TOPIC => false,
                _ => continue,
            };
            t0 = Some(t0.map_or(m.log_time, |t: u64| t.min(m.log_time)));
            raw.push((m.log_time, is_cmd, m.data.into_owned()));
        }
        let t0 = t0.unwrap_or(0);
        for (lt, is_cmd, data) in raw {
            let t = (lt - t0) as f64 * 1e-9;
            if is_cmd {
                let d = lowlevel_codec::decode::<LowCmd_>(&data)
                    .map_err(|e| GapError::Log(format!("a LowCmd at t = {t:.3} s: {e}")))?;
                log.commands.push(command_from_msg(t, &d.value, model)?);
            } else {
                let d = lowlevel_codec::decode::<LowState_>(&data)
                    .map_err(|e| GapError::Log(format!("a LowState at t = {t:.3} s: {e}")))?;
                log.states.push(measurement_from_msg(t, &d.value, model)?);
            }
        }
        log.commands.sort_by(|a, b| a.t.total_cmp(&b.t));
        log.states.sort_by(|a, b| a.t.total_cmp(&b.t));
        log.validate(model.nj())?;
        Ok(log)
    }

    /// Writes the MCAP form `ulab record` writes (uncompressed chunks).
    pub fn write_mcap<W: Write + std::io::Seek>(&self, out: W, model: &RobotModel) -> Result<(), GapError> {
        self.write_mcap_with(out, model, recording::Compression::None)
    }

    /// Writes the MCAP form `ulab record` writes, chunks compressed with `compression`.
    pub fn write_mcap_with<W: Write + std::io::Seek>(
        &self,
        out: W,
        model: &RobotModel,
        compression: recording::Compression,
    ) -> Result<(), GapError> {
        let io = GapError::McapWrite;
        let opts = recording::write_options(concat!("ulab gap ", env!("CARGO_PKG_VERSION")), compression);
        let mut w = opts.create(out).map_err(io)?;
        let mut ids = [0u16; 2];
        for (k, (topic, kind)) in
            [(LOWCMD_TOPIC, unitree_idl::MessageType::HgLowCmd), (LOWSTATE_TOPIC, unitree_idl::MessageType::HgLowState)]
                .into_iter()
                .enumerate()
        {
            ids[k] = recording::add_topic(&mut w, topic, kind.dds_type_name()).map_err(io)?;
        }
        let enc = Encoding { representation: Representation::Xcdr1, endianness: Endianness::Little };
        // Merge by time so that the file is in log-time order like a recording.
        let (mut i, mut j, mut seq) = (0usize, 0usize, [0u32; 2]);
        let t_ns = |t: f64| (t.max(0.0) * 1e9).round() as u64 + 1_000_000_000;
        while i < self.commands.len() || j < self.states.len() {
            let take_cmd =
                j >= self.states.len() || (i < self.commands.len() && self.commands[i].t <= self.states[j].t);
            let (ch, t, bytes) = if take_cmd {
                let c = &self.commands[i];
                i += 1;
                let mut m = command_to_msg(c, model);
                lowlevel_codec::seal(&mut m);
                (0, c.t, lowlevel_codec::encode(&m, enc))
            } else {
                let s = &self.states[j];
                j += 1;
                let mut m = measurement_to_msg(s, model, j as u32);
                lowlevel_codec::seal(&mut m);
                (1, s.t, lowlevel_codec::encode(&m, enc))
            };
            let hdr = mcap::records::MessageHeader {
                channel_id: ids[ch],
                sequence: seq[ch],
                log_time: t_ns(t),
                publish_time: t_ns(t),
            };
            seq[ch] = seq[ch].wrapping_add(1);
            w.write_to_known_channel(&hdr, &bytes).map_err(io)?;
        }
        w.finish().map_err(io)?;
        Ok(())
    }

    /// Reads the CSV pair `ulab log export` writes for a recording: `rt_lowcmd.csv` and `rt_lowstate.csv` (columns
    /// [`CSV_COLUMNS_DOC`]).
    pub fn from_export_csv(lowcmd_csv: &str, lowstate_csv: &str, model: &RobotModel) -> Result<Self, GapError> {
        let nj = model.nj();
        let mut log = RobotLog::default();
        let cmd_rows = csv_rows(lowcmd_csv, "rt_lowcmd.csv")?;
        let st_rows = csv_rows(lowstate_csv, "rt_lowstate.csv")?;
        let t0 = cmd_rows
            .1
            .iter()
            .chain(&st_rows.1)
            .filter_map(|r| r.first().and_then(|x| x.parse::<u64>().ok()))
            .min()
            .unwrap_or(0);
        let (hdr, rows) = cmd_rows;
        let col = |hdr: &[String], name: &str| -> Result<usize, GapError> {
            hdr.iter().position(|h| h == name).ok_or_else(|| GapError::Log(format!("CSV column {name} missing")))
        };
        let num = |row: &[String], k: usize, what: &str| -> Result<f64, GapError> {
            row.get(k)
                .and_then(|x| x.parse::<f64>().ok())
                .ok_or_else(|| GapError::Log(format!("CSV: {what} is not a number")))
        };
        let time = |row: &[String], k: usize| -> Result<f64, GapError> {
            let ns = row
                .get(k)
                .and_then(|x| x.parse::<u64>().ok())
                .ok_or_else(|| GapError::Log("CSV: bad log_time_ns".into()))?;
            Ok(ns.saturating_sub(t0) as f64 * 1e-9)
        };
        let tcol = col(&hdr, "log_time_ns")?;
        let field =
            |hdr: &[String], arr: &str, j: usize, f: &str| col(hdr, &element_column(arr, model.joints[j].slot, f));
        let idx = |hdr: &[String], arr: &str, f: &str| -> Result<Vec<usize>, GapError> {
            (0..nj).map(|j| field(hdr, arr, j, f)).collect()
        };
        let (iq, idq, ikp, ikd, itau, imode) = (
            idx(&hdr, "motor_cmd", "q")?,
            idx(&hdr, "motor_cmd", "dq")?,
            idx(&hdr, "motor_cmd", "kp")?,
            idx(&hdr, "motor_cmd", "kd")?,
            idx(&hdr, "motor_cmd", "tau")?,
            idx(&hdr, "motor_cmd", "mode")?,
        );
        for r in &rows {
            let mut c = Command {
                t: time(r, tcol)?,
                q: vec![0.0; nj],
                dq: vec![0.0; nj],
                kp: vec![0.0; nj],
                kd: vec![0.0; nj],
                tau: vec![0.0; nj],
            };
            for j in 0..nj {
                c.q[j] = num(r, iq[j], "q")?;
                if num(r, imode[j], "mode")? != 0.0 {
                    c.dq[j] = num(r, idq[j], "dq")?;
                    c.kp[j] = num(r, ikp[j], "kp")?;
                    c.kd[j] = num(r, ikd[j], "kd")?;
                    c.tau[j] = num(r, itau[j], "tau")?;
                }
            }
            log.commands.push(c);
        }
        let (hdr, rows) = st_rows;
        let tcol = col(&hdr, "log_time_ns")?;
        let imu = |f: &str, n: usize| -> Result<Vec<usize>, GapError> {
            (0..n).map(|i| col(&hdr, &array_column(&format!("imu_state.{f}"), i))).collect()
        };
        let (iquat, igyro, iacc) = (imu("quaternion", 4)?, imu("gyroscope", 3)?, imu("accelerometer", 3)?);
        let (iq, idq, itau) =
            (idx(&hdr, "motor_state", "q")?, idx(&hdr, "motor_state", "dq")?, idx(&hdr, "motor_state", "tau_est")?);
        for r in &rows {
            let mut m = Measurement {
                t: time(r, tcol)?,
                q: vec![0.0; nj],
                dq: vec![0.0; nj],
                tau: vec![0.0; nj],
                quat: [0.0; 4],
                gyro: [0.0; 3],
                acc: [0.0; 3],
            };
            for j in 0..nj {
                m.q[j] = num(r, iq[j], "q")?;
                m.dq[j] = num(r, idq[j], "dq")?;
                m.tau[j] = num(r, itau[j], "tau_est")?;
            }
            for (q, &k) in m.quat.iter_mut().zip(&iquat) {
                *q = num(r, k, "quaternion")?;
            }
            for i in 0..3 {
                m.gyro[i] = num(r, igyro[i], "gyroscope")?;
                m.acc[i] = num(r, iacc[i], "accelerometer")?;
            }
            log.states.push(m);
        }
        log.commands.sort_by(|a, b| a.t.total_cmp(&b.t));
        log.states.sort_by(|a, b| a.t.total_cmp(&b.t));
        log.validate(nj)?;
        Ok(log)
    }
}

/// Header and rows of a CSV without quoted commas (the numeric exports `ulab log export` writes).
fn csv_rows(text: &str, name: &str) -> Result<(Vec<String>, Vec<Vec<String>>), GapError> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let hdr: Vec<String> = lines
        .next()
        .ok_or_else(|| GapError::Log(format!("{name} is empty")))?
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(|s| s.trim().to_string()).collect()).collect();
    Ok((hdr, rows))
}

fn slot_of(model: &RobotModel, j: usize, len: usize) -> Result<usize, GapError> {
    let s = model.joints[j].slot;
    if s >= len {
        return Err(GapError::Log(format!(
            "joint {} has slot {s}, beyond the message's {len} motors",
            model.joints[j].name
        )));
    }
    Ok(s)
}

fn command_from_msg(t: f64, m: &LowCmd_, model: &RobotModel) -> Result<Command, GapError> {
    let nj = model.nj();
    let mut c =
        Command { t, q: vec![0.0; nj], dq: vec![0.0; nj], kp: vec![0.0; nj], kd: vec![0.0; nj], tau: vec![0.0; nj] };
    for j in 0..nj {
        let mc = &m.motor_cmd[slot_of(model, j, m.motor_cmd.len())?];
        c.q[j] = f64::from(mc.q);
        if mc.mode != 0 {
            c.dq[j] = f64::from(mc.dq);
            c.kp[j] = f64::from(mc.kp);
            c.kd[j] = f64::from(mc.kd);
            c.tau[j] = f64::from(mc.tau);
        }
    }
    Ok(c)
}

fn measurement_from_msg(t: f64, m: &LowState_, model: &RobotModel) -> Result<Measurement, GapError> {
    let nj = model.nj();
    let mut s = Measurement {
        t,
        q: vec![0.0; nj],
        dq: vec![0.0; nj],
        tau: vec![0.0; nj],
        quat: m.imu_state.quaternion.map(f64::from),
        gyro: m.imu_state.gyroscope.map(f64::from),
        acc: m.imu_state.accelerometer.map(f64::from),
    };
    for j in 0..nj {
        let ms = &m.motor_state[slot_of(model, j, m.motor_state.len())?];
        s.q[j] = f64::from(ms.q);
        s.dq[j] = f64::from(ms.dq);
        s.tau[j] = f64::from(ms.tau_est);
    }
    Ok(s)
}

fn command_to_msg(c: &Command, model: &RobotModel) -> LowCmd_ {
    let mut m = LowCmd_::zeroed_value();
    for (j, joint) in model.joints.iter().enumerate() {
        if let Some(mc) = m.motor_cmd.get_mut(joint.slot) {
            mc.mode = 1;
            mc.q = c.q[j] as f32;
            mc.dq = c.dq[j] as f32;
            mc.kp = c.kp[j] as f32;
            mc.kd = c.kd[j] as f32;
            mc.tau = c.tau[j] as f32;
        }
    }
    m
}

fn measurement_to_msg(s: &Measurement, model: &RobotModel, tick: u32) -> LowState_ {
    let mut m = LowState_::zeroed_value();
    m.tick = tick;
    m.imu_state.quaternion = s.quat.map(|x| x as f32);
    m.imu_state.gyroscope = s.gyro.map(|x| x as f32);
    m.imu_state.accelerometer = s.acc.map(|x| x as f32);
    for (j, joint) in model.joints.iter().enumerate() {
        if let Some(ms) = m.motor_state.get_mut(joint.slot) {
            ms.mode = 1;
            ms.q = s.q[j] as f32;
            ms.dq = s.dq[j] as f32;
            ms.tau_est = s.tau[j] as f32;
        }
    }
    m
}

/// `IdlStruct::zeroed` under a name that does not need the trait in scope at call sites.
trait Zeroed {
    fn zeroed_value() -> Self;
}
impl<T: unitree_idl::IdlStruct> Zeroed for T {
    fn zeroed_value() -> Self {
        T::zeroed()
    }
}

/// `n` states of a robot holding its default pose, 2 ms apart (a test fixture for the stages that read states).
#[cfg(test)]
pub(crate) fn still_states(model: &RobotModel, n: usize) -> Vec<Measurement> {
    let q = model.default_q();
    (0..n)
        .map(|k| Measurement {
            t: k as f64 * 0.002,
            q: q.clone(),
            dq: vec![0.0; model.nj()],
            tau: vec![0.0; model.nj()],
            quat: [1.0, 0.0, 0.0, 0.0],
            gyro: [0.0; 3],
            acc: [0.0; 3],
        })
        .collect()
}
