//! Command codes and identifiers: `can_id = (command << 2) | device_id`.

/// Fingers on the bus, in bus order: index, middle, ring, thumb.
pub const FINGERS: usize = 4;
/// Joints of one finger, proximal (roll) to distal.
pub const JOINTS_PER_FINGER: usize = 4;
/// Joints of the hand, finger-major in bus order.
pub const JOINTS: usize = FINGERS * JOINTS_PER_FINGER;

/// The hand's device id (0–3, set with `CONFIG`); a hand leaves the factory as 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct DeviceId(u8);

impl DeviceId {
    /// Device id 0, the factory setting.
    pub const DEFAULT: DeviceId = DeviceId(0);

    /// A device id, `None` above 3 (two bits of the identifier).
    pub const fn new(id: u8) -> Option<DeviceId> {
        if id <= 3 { Some(DeviceId(id)) } else { None }
    }

    /// The id's value, 0–3.
    pub const fn get(self) -> u8 {
        self.0
    }
}

/// A command code: the identifier's upper nine bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// Servo on (`0x40`, no data).
    SystemOn,
    /// Servo off (`0x41`, no data).
    SystemOff,
    /// Joint PWM of one finger (`0x60`–`0x63`).
    SetTorque(u8),
    /// Streaming periods (`0x81`).
    SetPeriod,
    /// Device id or RS-485 baud (`0x68`).
    Config,
    /// Hand information (`0x80`, remote request; reply of 7 bytes).
    HandInfo,
    /// Serial number (`0x88`, remote request; reply of 8 ASCII bytes).
    Serial,
    /// Encoder counts of one finger (`0x20`–`0x23`, remote request or streamed).
    FingerPose(u8),
    /// Orientation of the hand's IMU (`0x30`, remote request).
    Imu,
    /// Joint temperatures of one finger (`0x38`–`0x3B`, remote request).
    Temperature(u8),
}

impl Command {
    /// The command's code (9 bits).
    pub const fn code(self) -> u16 {
        match self {
            Command::SystemOn => 0x40,
            Command::SystemOff => 0x41,
            Command::SetTorque(f) => 0x60 + (f & 3) as u16,
            Command::SetPeriod => 0x81,
            Command::Config => 0x68,
            Command::HandInfo => 0x80,
            Command::Serial => 0x88,
            Command::FingerPose(f) => 0x20 + (f & 3) as u16,
            Command::Imu => 0x30,
            Command::Temperature(f) => 0x38 + (f & 3) as u16,
        }
    }

    /// The command of a code, `None` for a code the protocol does not have.
    pub const fn from_code(code: u16) -> Option<Command> {
        Some(match code {
            0x40 => Command::SystemOn,
            0x41 => Command::SystemOff,
            0x60..=0x63 => Command::SetTorque((code - 0x60) as u8),
            0x81 => Command::SetPeriod,
            0x68 => Command::Config,
            0x80 => Command::HandInfo,
            0x88 => Command::Serial,
            0x20..=0x23 => Command::FingerPose((code - 0x20) as u8),
            0x30 => Command::Imu,
            0x38..=0x3B => Command::Temperature((code - 0x38) as u8),
            _ => return None,
        })
    }

    /// The 11-bit identifier of this command for `device`.
    pub const fn id(self, device: DeviceId) -> u16 {
        (self.code() << 2) | device.0 as u16
    }

    /// Split an 11-bit identifier into its command code and device id.
    pub const fn split_id(id: u16) -> (u16, DeviceId) {
        ((id & 0x7FF) >> 2, DeviceId((id & 3) as u8))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_are_the_command_shifted_past_the_device_id() {
        let d0 = DeviceId::DEFAULT;
        assert_eq!(Command::SetTorque(0).id(d0), 0x180);
        assert_eq!(Command::SetTorque(3).id(d0), 0x18C);
        assert_eq!(Command::FingerPose(0).id(d0), 0x080);
        assert_eq!(Command::FingerPose(3).id(d0), 0x08C);
        assert_eq!(Command::HandInfo.id(d0), 0x200);
        assert_eq!(Command::Temperature(0).id(d0), 0x0E0);
        assert_eq!(Command::SetPeriod.id(d0), 0x204);
        assert_eq!(Command::Serial.id(d0), 0x220);
        assert_eq!(Command::SystemOn.id(d0), 0x100);
        assert_eq!(Command::SystemOff.id(d0), 0x104);
        let d2 = DeviceId::new(2).unwrap();
        assert_eq!(Command::SetTorque(1).id(d2), 0x186);
        assert_eq!(Command::split_id(0x186), (0x61, d2));
        assert_eq!(DeviceId::new(4), None);
        for code in 0..0x200u16 {
            if let Some(c) = Command::from_code(code) {
                assert_eq!(c.code(), code);
            }
        }
    }
}
