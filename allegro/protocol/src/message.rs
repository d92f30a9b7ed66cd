//! The messages: what the host sends ([`HostCommand`]) and what the hand answers
//! ([`HandReply`]), each encoded into and decoded from any [`embedded_can::Frame`].

use embedded_can::{Frame, Id};

use crate::frame::standard_id;
use crate::ids::{Command, DeviceId, FINGERS, JOINTS_PER_FINGER};

/// Streaming periods of `SET_PERIOD`, in milliseconds; 0 stops that stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Periods {
    /// Finger poses (3 ms: ≈ 333 Hz, what the vendor's drivers ask for).
    pub position_ms: u16,
    /// The IMU.
    pub imu_ms: u16,
    /// Temperatures.
    pub temperature_ms: u16,
}

impl Periods {
    /// What the drivers start with: poses every 3 ms, nothing else.
    pub const STREAM_POSES: Periods = Periods {
        position_ms: 3,
        imu_ms: 0,
        temperature_ms: 0,
    };
    /// All streams stopped (shutdown).
    pub const STOPPED: Periods = Periods {
        position_ms: 0,
        imu_ms: 0,
        temperature_ms: 0,
    };
}

/// What the host sends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HostCommand {
    /// Servo on: the hand applies the torques it is sent.
    SystemOn,
    /// Servo off: the motors are free.
    SystemOff,
    /// PWM of one finger's four joints (bus order), little-endian i16.
    SetTorque {
        /// Finger 0–3 (index, middle, ring, thumb).
        finger: u8,
        /// PWM of joints 0..3, proximal to distal.
        pwm: [i16; JOINTS_PER_FINGER],
    },
    /// Streaming periods.
    SetPeriod(Periods),
    /// `CONFIG` with its six raw bytes (device id `data[0] = id | 0x80`, or RS-485 baud).
    Config([u8; 6]),
    /// A remote request for one of the hand's replies.
    Request(Request),
}

/// What the host can ask for with a remote request (RTR).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Request {
    /// Hand information ([`HandInfo`]).
    HandInfo,
    /// The serial number.
    Serial,
    /// One finger's encoder counts.
    FingerPose(u8),
    /// The IMU's orientation.
    Imu,
    /// One finger's joint temperatures.
    Temperature(u8),
}

impl Request {
    fn command(self) -> Command {
        match self {
            Request::HandInfo => Command::HandInfo,
            Request::Serial => Command::Serial,
            Request::FingerPose(f) => Command::FingerPose(f),
            Request::Imu => Command::Imu,
            Request::Temperature(f) => Command::Temperature(f),
        }
    }
}

/// Left or right hand (`HAND_INFO` byte 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HandType {
    /// 0.
    Right,
    /// 1.
    Left,
    /// Any other value, kept.
    Other(u8),
}

impl HandType {
    fn from_byte(b: u8) -> HandType {
        match b {
            0 => HandType::Right,
            1 => HandType::Left,
            other => HandType::Other(other),
        }
    }

    fn byte(self) -> u8 {
        match self {
            HandType::Right => 0,
            HandType::Left => 1,
            HandType::Other(b) => b,
        }
    }
}

/// The status byte of `HAND_INFO`. The sources agree on bits 0–2 and differ beyond, so the
/// raw byte is kept beside the decoded bits.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Status(pub u8);

impl Status {
    /// Bit 0: the servo is on.
    pub fn servo_on(self) -> bool {
        self.0 & 0x01 != 0
    }
    /// Bit 1: the hand reports a high-temperature fault.
    pub fn high_temperature(self) -> bool {
        self.0 & 0x02 != 0
    }
    /// Bit 2: the hand reports an internal communication fault.
    pub fn internal_communication_fault(self) -> bool {
        self.0 & 0x04 != 0
    }
}

/// `HAND_INFO`'s reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct HandInfo {
    /// Hardware version (`0x0402`: a V4; its high byte is the hand's version).
    pub hardware_version: u16,
    /// Firmware version.
    pub firmware_version: u16,
    /// Left or right.
    pub hand_type: HandType,
    /// The hand's temperature (°C).
    pub temperature_c: u8,
    /// Status bits.
    pub status: Status,
}

/// What the hand sends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HandReply {
    /// One finger's encoder counts (streamed, or the answer to a request).
    FingerPose {
        /// Finger 0–3.
        finger: u8,
        /// Counts of joints 0..3 ([`crate::scale::counts_to_radians`]).
        counts: [i16; JOINTS_PER_FINGER],
    },
    /// Hand information.
    HandInfo(HandInfo),
    /// The serial number, eight ASCII bytes.
    Serial([u8; 8]),
    /// One finger's joint temperatures (°C).
    Temperature {
        /// Finger 0–3.
        finger: u8,
        /// Temperatures of joints 0..3.
        celsius: [u8; JOINTS_PER_FINGER],
    },
    /// The IMU's raw roll, pitch, yaw.
    Imu([u16; 3]),
}

/// Why a frame is not a message of this protocol. Decoding never panics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DecodeError {
    /// An extended (29-bit) identifier: the hand uses standard ones only.
    ExtendedId(u32),
    /// No command has this code.
    UnknownCommand(u16),
    /// A command with the wrong number of data bytes.
    BadLength {
        /// The command.
        command: Command,
        /// Bytes expected.
        expected: usize,
        /// Bytes received.
        got: usize,
    },
    /// A data frame where a remote request was expected, or the reverse.
    WrongKind {
        /// The command.
        command: Command,
        /// Whether the frame was a remote request.
        remote: bool,
    },
    /// A command that travels the other way (a host command where a reply was expected, or
    /// a reply where a host command was expected).
    WrongDirection(Command),
}

impl core::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DecodeError::ExtendedId(id) => {
                write!(f, "extended id {id:#010x} (the hand uses 11-bit ids)")
            }
            DecodeError::UnknownCommand(c) => write!(f, "unknown command {c:#04x}"),
            DecodeError::BadLength {
                command,
                expected,
                got,
            } => {
                write!(f, "{command:?} with {got} data bytes (expected {expected})")
            }
            DecodeError::WrongKind {
                command,
                remote: true,
            } => {
                write!(f, "{command:?} as a remote request (expected data)")
            }
            DecodeError::WrongKind {
                command,
                remote: false,
            } => {
                write!(f, "{command:?} with data (expected a remote request)")
            }
            DecodeError::WrongDirection(c) => write!(f, "{c:?} travels the other way"),
        }
    }
}

impl core::error::Error for DecodeError {}

fn le_i16x4(d: &[u8]) -> [i16; 4] {
    core::array::from_fn(|i| i16::from_le_bytes([d[2 * i], d[2 * i + 1]]))
}

fn i16x4_le(v: &[i16; 4]) -> [u8; 8] {
    let mut out = [0; 8];
    for (i, x) in v.iter().enumerate() {
        out[2 * i..2 * i + 2].copy_from_slice(&x.to_le_bytes());
    }
    out
}

/// The command and device of a frame, refusing extended ids and unknown codes.
fn command_of<F: Frame>(frame: &F) -> Result<(Command, DeviceId), DecodeError> {
    let raw = match frame.id() {
        Id::Standard(s) => s.as_raw(),
        Id::Extended(e) => return Err(DecodeError::ExtendedId(e.as_raw())),
    };
    let (code, device) = Command::split_id(raw);
    let command = Command::from_code(code).ok_or(DecodeError::UnknownCommand(code))?;
    Ok((command, device))
}

fn expect_len<F: Frame>(frame: &F, command: Command, expected: usize) -> Result<(), DecodeError> {
    if frame.is_remote_frame() {
        return Err(DecodeError::WrongKind {
            command,
            remote: true,
        });
    }
    let got = frame.data().len();
    if got != expected {
        return Err(DecodeError::BadLength {
            command,
            expected,
            got,
        });
    }
    Ok(())
}

fn finger_of(f: u8) -> u8 {
    f % FINGERS as u8
}

impl HostCommand {
    /// The frame of this command for `device`; `None` only where the frame type refuses a
    /// standard id or 8 bytes (no conforming type does).
    pub fn to_frame<F: Frame>(&self, device: DeviceId) -> Option<F> {
        let id = |c: Command| standard_id(c.id(device));
        match *self {
            HostCommand::SystemOn => F::new(id(Command::SystemOn), &[]),
            HostCommand::SystemOff => F::new(id(Command::SystemOff), &[]),
            HostCommand::SetTorque { finger, pwm } => {
                F::new(id(Command::SetTorque(finger_of(finger))), &i16x4_le(&pwm))
            }
            HostCommand::SetPeriod(p) => {
                let mut d = [0; 6];
                d[0..2].copy_from_slice(&p.position_ms.to_le_bytes());
                d[2..4].copy_from_slice(&p.imu_ms.to_le_bytes());
                d[4..6].copy_from_slice(&p.temperature_ms.to_le_bytes());
                F::new(id(Command::SetPeriod), &d)
            }
            HostCommand::Config(d) => F::new(id(Command::Config), &d),
            HostCommand::Request(r) => F::new_remote(id(r.command()), 0),
        }
    }

    /// Decode a frame the host sent (what the hand's firmware, or the emulator, reads).
    pub fn from_frame<F: Frame>(frame: &F) -> Result<(HostCommand, DeviceId), DecodeError> {
        let (command, device) = command_of(frame)?;
        let remote = frame.is_remote_frame();
        let d = frame.data();
        let request = |r: Request| {
            if remote {
                Ok(HostCommand::Request(r))
            } else {
                Err(DecodeError::WrongKind {
                    command,
                    remote: false,
                })
            }
        };
        let cmd = match command {
            Command::SystemOn => {
                expect_len(frame, command, 0)?;
                HostCommand::SystemOn
            }
            Command::SystemOff => {
                expect_len(frame, command, 0)?;
                HostCommand::SystemOff
            }
            Command::SetTorque(finger) => {
                expect_len(frame, command, 8)?;
                HostCommand::SetTorque {
                    finger,
                    pwm: le_i16x4(d),
                }
            }
            Command::SetPeriod => {
                expect_len(frame, command, 6)?;
                let u = |i: usize| u16::from_le_bytes([d[i], d[i + 1]]);
                HostCommand::SetPeriod(Periods {
                    position_ms: u(0),
                    imu_ms: u(2),
                    temperature_ms: u(4),
                })
            }
            Command::Config => {
                expect_len(frame, command, 6)?;
                let mut b = [0; 6];
                b.copy_from_slice(d);
                HostCommand::Config(b)
            }
            Command::HandInfo => request(Request::HandInfo)?,
            Command::Serial => request(Request::Serial)?,
            Command::FingerPose(f) => request(Request::FingerPose(f))?,
            Command::Imu => request(Request::Imu)?,
            Command::Temperature(f) => request(Request::Temperature(f))?,
        };
        Ok((cmd, device))
    }
}

impl HandReply {
    /// The frame of this reply from `device`.
    pub fn to_frame<F: Frame>(&self, device: DeviceId) -> Option<F> {
        let id = |c: Command| standard_id(c.id(device));
        match *self {
            HandReply::FingerPose { finger, counts } => F::new(
                id(Command::FingerPose(finger_of(finger))),
                &i16x4_le(&counts),
            ),
            HandReply::HandInfo(i) => {
                let h = i.hardware_version.to_le_bytes();
                let f = i.firmware_version.to_le_bytes();
                F::new(
                    id(Command::HandInfo),
                    &[
                        h[0],
                        h[1],
                        f[0],
                        f[1],
                        i.hand_type.byte(),
                        i.temperature_c,
                        i.status.0,
                    ],
                )
            }
            HandReply::Serial(s) => F::new(id(Command::Serial), &s),
            HandReply::Temperature { finger, celsius } => {
                F::new(id(Command::Temperature(finger_of(finger))), &celsius)
            }
            HandReply::Imu(v) => {
                let mut d = [0; 6];
                for (i, x) in v.iter().enumerate() {
                    d[2 * i..2 * i + 2].copy_from_slice(&x.to_le_bytes());
                }
                F::new(id(Command::Imu), &d)
            }
        }
    }

    /// Decode a frame the hand sent (what the host's driver reads). Remote requests (the
    /// host's own, seen on a shared bus) and host commands are [`DecodeError::WrongKind`] and
    /// [`DecodeError::WrongDirection`].
    pub fn from_frame<F: Frame>(frame: &F) -> Result<(HandReply, DeviceId), DecodeError> {
        let (command, device) = command_of(frame)?;
        let d = frame.data();
        let reply = match command {
            Command::FingerPose(finger) => {
                expect_len(frame, command, 8)?;
                HandReply::FingerPose {
                    finger,
                    counts: le_i16x4(d),
                }
            }
            Command::HandInfo => {
                expect_len(frame, command, 7)?;
                HandReply::HandInfo(HandInfo {
                    hardware_version: u16::from_le_bytes([d[0], d[1]]),
                    firmware_version: u16::from_le_bytes([d[2], d[3]]),
                    hand_type: HandType::from_byte(d[4]),
                    temperature_c: d[5],
                    status: Status(d[6]),
                })
            }
            Command::Serial => {
                expect_len(frame, command, 8)?;
                let mut s = [0; 8];
                s.copy_from_slice(d);
                HandReply::Serial(s)
            }
            Command::Temperature(finger) => {
                expect_len(frame, command, 4)?;
                HandReply::Temperature {
                    finger,
                    celsius: [d[0], d[1], d[2], d[3]],
                }
            }
            Command::Imu => {
                expect_len(frame, command, 6)?;
                let u = |i: usize| u16::from_le_bytes([d[i], d[i + 1]]);
                HandReply::Imu([u(0), u(2), u(4)])
            }
            other => return Err(DecodeError::WrongDirection(other)),
        };
        Ok((reply, device))
    }
}
