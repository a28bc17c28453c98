//! H.264 MP4 through an `ffmpeg` child process: raw RGB frames go into its standard input, it writes a file a
//! browser plays (yuv420p, the `moov` index at the front). Also the decoder side, for tests that check a video
//! with an independent decoder.
use crate::raster::Frame;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::thread::JoinHandle;

/// How much of ffmpeg's standard error an error keeps (its last bytes).
const STDERR_TAIL: usize = 2000;

/// Why a video could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum VideoError {
    /// No ffmpeg anywhere this crate looks.
    #[error(
        "ffmpeg not found (tried: {tried}); install it with `bash scripts/setup.sh` (it puts the `imageio-ffmpeg` \
         package, which bundles a static ffmpeg, into the project's Python venv), or `apt-get install ffmpeg`, or \
         point ULAB_FFMPEG at an ffmpeg binary"
    )]
    NotFound {
        /// Where it looked.
        tried: String,
    },
    /// ffmpeg could not be started.
    #[error("cannot start {}", path.display())]
    Spawn {
        /// The binary.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A frame does not have the size the video was opened with.
    #[error("frame is {got:?}, the video is {want:?}")]
    FrameSize {
        /// The frame's width and height.
        got: (u32, u32),
        /// The video's.
        want: (u32, u32),
    },
    /// Writing to ffmpeg failed (it exited early: see its messages).
    #[error("ffmpeg stopped taking frames; it said: {stderr}")]
    Pipe {
        /// The tail of ffmpeg's standard error.
        stderr: String,
        /// The pipe's error.
        #[source]
        source: std::io::Error,
    },
    /// ffmpeg exited with a failure.
    #[error("ffmpeg failed ({status}); it said: {stderr}")]
    Failed {
        /// Its exit status.
        status: std::process::ExitStatus,
        /// The tail of its standard error.
        stderr: String,
    },
    /// Waiting for ffmpeg failed.
    #[error("waiting for ffmpeg")]
    Wait(#[source] std::io::Error),
    /// ffmpeg's description of a decoded file could not be understood.
    #[error("cannot read ffmpeg's description of the video: {0}")]
    Probe(String),
}

/// Finds ffmpeg: `$ULAB_FFMPEG`, else the static binary of the `imageio-ffmpeg` package in the project's Python
/// (`$ULAB_PYTHON`, set by `scripts/env.sh`), else `ffmpeg` on the `PATH`.
pub fn find_ffmpeg() -> Result<PathBuf, VideoError> {
    let mut tried = Vec::new();
    if let Some(p) = std::env::var_os("ULAB_FFMPEG") {
        let p = PathBuf::from(p);
        if runs(&p) {
            return Ok(p);
        }
        tried.push(format!("ULAB_FFMPEG={}", p.display()));
    }
    match std::env::var_os("ULAB_PYTHON") {
        Some(py) => {
            let out = Command::new(&py)
                .args(["-c", "import imageio_ffmpeg; print(imageio_ffmpeg.get_ffmpeg_exe())"])
                .stdin(Stdio::null())
                .stderr(Stdio::null())
                .output();
            if let Ok(out) = out {
                let p = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
                if out.status.success() && runs(&p) {
                    return Ok(p);
                }
            }
            tried.push(format!("imageio_ffmpeg in {}", Path::new(&py).display()));
        }
        None => tried.push("imageio_ffmpeg (ULAB_PYTHON unset: source scripts/env.sh)".into()),
    }
    let p = PathBuf::from("ffmpeg");
    if runs(&p) {
        return Ok(p);
    }
    tried.push("ffmpeg on PATH".into());
    Err(VideoError::NotFound { tried: tried.join(", ") })
}

fn runs(p: &Path) -> bool {
    Command::new(p)
        .arg("-version")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Reads a child's standard error on a thread (so that a chatty ffmpeg never blocks on a full pipe) and keeps
/// its tail.
fn collect_stderr(child: &mut Child) -> Option<JoinHandle<String>> {
    let mut err = child.stderr.take()?;
    Some(std::thread::spawn(move || {
        let mut tail: Vec<u8> = Vec::new();
        let mut buf = [0u8; 4096];
        while let Ok(n) = err.read(&mut buf) {
            if n == 0 {
                break;
            }
            tail.extend_from_slice(&buf[..n]);
            if tail.len() > 2 * STDERR_TAIL {
                tail.drain(..tail.len() - STDERR_TAIL);
            }
        }
        let s = String::from_utf8_lossy(&tail[tail.len().saturating_sub(STDERR_TAIL)..]).into_owned();
        s.trim().to_owned()
    }))
}

/// An MP4 being written: frames in, H.264 out. [`finish`](Self::finish) completes the file; a writer dropped
/// without it kills ffmpeg (the file is then incomplete) and waits for it, so no child is left behind.
#[derive(Debug)]
pub struct VideoWriter {
    child: Child,
    stdin: Option<ChildStdin>,
    stderr: Option<JoinHandle<String>>,
    size: (u32, u32),
    frames: u64,
    done: bool,
}

impl VideoWriter {
    /// Starts `ffmpeg` writing `out` (overwritten) at `fps` frames per second of `width` x `height` (even).
    pub fn create(ffmpeg: &Path, out: &Path, width: u32, height: u32, fps: f64) -> Result<Self, VideoError> {
        let size = format!("{width}x{height}");
        let mut child = Command::new(ffmpeg)
            .args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y"])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-s", &size, "-r", &format!("{fps}"), "-i", "-"])
            .args(["-an", "-c:v", "libx264", "-preset", "veryfast", "-crf", "23", "-pix_fmt", "yuv420p"])
            .args(["-movflags", "+faststart", "-f", "mp4"])
            .arg(out)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|source| VideoError::Spawn { path: ffmpeg.to_owned(), source })?;
        let stdin = child.stdin.take();
        let stderr = collect_stderr(&mut child);
        Ok(VideoWriter { child, stdin, stderr, size: (width, height), frames: 0, done: false })
    }

    /// Process id of the ffmpeg child.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Appends a frame.
    pub fn write(&mut self, frame: &Frame) -> Result<(), VideoError> {
        let got = (frame.width(), frame.height());
        if got != self.size {
            return Err(VideoError::FrameSize { got, want: self.size });
        }
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(VideoError::Pipe {
                stderr: String::new(),
                source: std::io::Error::new(std::io::ErrorKind::BrokenPipe, "ffmpeg's input is closed"),
            });
        };
        if let Err(source) = stdin.write_all(frame.rgb()) {
            // ffmpeg is gone or going: wait for it and say what it said.
            self.stdin = None;
            let _ = self.child.kill();
            let _ = self.child.wait();
            self.done = true;
            let stderr = self.stderr.take().and_then(|h| h.join().ok()).unwrap_or_default();
            return Err(VideoError::Pipe { stderr, source });
        }
        self.frames += 1;
        Ok(())
    }

    /// Closes the input, waits for ffmpeg to finish the file and returns the number of frames.
    pub fn finish(mut self) -> Result<u64, VideoError> {
        drop(self.stdin.take());
        let status = self.child.wait().map_err(VideoError::Wait)?;
        self.done = true;
        let stderr = self.stderr.take().and_then(|h| h.join().ok()).unwrap_or_default();
        if !status.success() {
            return Err(VideoError::Failed { status, stderr });
        }
        Ok(self.frames)
    }
}

impl Drop for VideoWriter {
    fn drop(&mut self) {
        if !self.done {
            drop(self.stdin.take());
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        if let Some(h) = self.stderr.take() {
            let _ = h.join();
        }
    }
}

/// What ffmpeg says about the video stream of a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StreamInfo {
    /// Codec name (`h264`).
    pub codec: String,
    /// Pixel format (`yuv420p`).
    pub pix_fmt: String,
    /// Width (pixels).
    pub width: u32,
    /// Height (pixels).
    pub height: u32,
    /// ffmpeg's whole line about the stream.
    pub line: String,
}

/// Decodes `path` with ffmpeg into RGB frames, with ffmpeg's description of the video stream: the independent
/// check of a written video (tests).
pub fn decode(ffmpeg: &Path, path: &Path) -> Result<(StreamInfo, Vec<Frame>), VideoError> {
    let out = Command::new(ffmpeg)
        .args(["-hide_banner", "-nostdin", "-i"])
        .arg(path)
        .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
        .stdin(Stdio::null())
        .output()
        .map_err(|source| VideoError::Spawn { path: ffmpeg.to_owned(), source })?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        let tail = &stderr[stderr.len().saturating_sub(STDERR_TAIL)..];
        return Err(VideoError::Failed { status: out.status, stderr: tail.trim().to_owned() });
    }
    let info = stream_info(&stderr)?;
    let n = info.width as usize * info.height as usize * 3;
    if n == 0 || out.stdout.len() % n != 0 {
        return Err(VideoError::Probe(format!(
            "{} bytes of frames of {}x{}",
            out.stdout.len(),
            info.width,
            info.height
        )));
    }
    let frames = out.stdout.chunks(n).filter_map(|c| Frame::from_rgb(info.width, info.height, c.to_vec())).collect();
    Ok((info, frames))
}

/// Parses the input's first video stream line: `Stream #0:0[0x1](und): Video: h264 (High) (avc1 / 0x31637661),
/// yuv420p(progressive), 64x48, ...`.
fn stream_info(stderr: &str) -> Result<StreamInfo, VideoError> {
    let line = stderr
        .lines()
        .take_while(|l| !l.starts_with("Output"))
        .find(|l| l.contains("Stream #") && l.contains("Video: "))
        .ok_or_else(|| VideoError::Probe("no video stream".into()))?;
    let after = line.split("Video: ").nth(1).unwrap_or_default();
    let codec = after.split([' ', ',']).next().unwrap_or_default().to_owned();
    let fields: Vec<&str> = after.split(", ").collect();
    let pix_fmt = fields.get(1).map(|f| f.split(['(', ' ']).next().unwrap_or_default().to_owned()).unwrap_or_default();
    let size = fields
        .iter()
        .filter_map(|f| f.split(' ').next())
        .find_map(|f| {
            let (w, h) = f.split_once('x')?;
            Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?))
        })
        .ok_or_else(|| VideoError::Probe(format!("no size in `{line}`")))?;
    Ok(StreamInfo { codec, pix_fmt, width: size.0, height: size.1, line: line.trim().to_owned() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stream_line_is_parsed() {
        let s = "Input #0, mov,mp4,m4a,3gp,3g2,mj2, from 'x.mp4':\n  Duration: 00:00:01.00\n  \
                 Stream #0:0[0x1](und): Video: h264 (High) (avc1 / 0x31637661), yuv420p(progressive), 640x360, \
                 120 kb/s, 15 fps\nOutput #0, rawvideo, to 'pipe:':\n  Stream #0:0: Video: rawvideo, rgb24, 640x360\n";
        let i = stream_info(s).expect("parsed");
        assert_eq!((i.codec.as_str(), i.pix_fmt.as_str(), i.width, i.height), ("h264", "yuv420p", 640, 360));
        assert!(stream_info("nothing").is_err());
    }
}
