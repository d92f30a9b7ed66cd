//! [`CanFrame`]: a classic CAN frame of our own, for buses that bring none (the in-process
//! bus of tests and the emulator). It implements [`embedded_can::Frame`], like SocketCAN's
//! and every embedded HAL's frames, so the protocol's encoders work on all of them.

use embedded_can::{ExtendedId, Frame, Id, StandardId};

/// A classic CAN frame: an identifier, up to 8 data bytes or a remote request of a length.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: Id,
    remote: bool,
    dlc: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// The identifier as a raw number (11 or 29 bits).
    pub fn raw_id(&self) -> u32 {
        match self.id {
            Id::Standard(s) => u32::from(s.as_raw()),
            Id::Extended(e) => e.as_raw(),
        }
    }

    /// Copy any other frame type's identifier, kind and bytes into ours.
    pub fn from_frame<F: Frame>(f: &F) -> CanFrame {
        let mut data = [0; 8];
        let n = f.data().len().min(8);
        data[..n].copy_from_slice(&f.data()[..n]);
        CanFrame {
            id: f.id(),
            remote: f.is_remote_frame(),
            dlc: f.dlc().min(8) as u8,
            data,
        }
    }

    /// This frame as any other frame type (`None` when that type refuses it).
    pub fn to_frame<F: Frame>(&self) -> Option<F> {
        if self.remote {
            F::new_remote(self.id, usize::from(self.dlc))
        } else {
            F::new(self.id, self.data())
        }
    }
}

impl Frame for CanFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        if data.len() > 8 {
            return None;
        }
        let mut d = [0; 8];
        d[..data.len()].copy_from_slice(data);
        Some(CanFrame {
            id: id.into(),
            remote: false,
            dlc: data.len() as u8,
            data: d,
        })
    }

    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        if dlc > 8 {
            return None;
        }
        Some(CanFrame {
            id: id.into(),
            remote: true,
            dlc: dlc as u8,
            data: [0; 8],
        })
    }

    fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }

    fn is_remote_frame(&self) -> bool {
        self.remote
    }

    fn id(&self) -> Id {
        self.id
    }

    fn dlc(&self) -> usize {
        usize::from(self.dlc)
    }

    fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..usize::from(self.dlc)]
        }
    }
}

/// A standard identifier from a raw value (masked to 11 bits, so never out of range).
pub fn standard_id(raw: u16) -> StandardId {
    StandardId::new(raw & 0x7FF).unwrap_or(StandardId::ZERO)
}

/// An extended identifier from a raw value (masked to 29 bits).
pub fn extended_id(raw: u32) -> ExtendedId {
    ExtendedId::new(raw & 0x1FFF_FFFF).unwrap_or(ExtendedId::ZERO)
}

impl core::fmt::Display for CanFrame {
    /// candump's form: `180 [8] 02 00 CB 00 42 00 25 00`, `080 [0] rtr`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.id {
            Id::Standard(_) => write!(f, "{:03X} [{}]", self.raw_id(), self.dlc)?,
            Id::Extended(_) => write!(f, "{:08X} [{}]", self.raw_id(), self.dlc)?,
        }
        if self.remote {
            return f.write_str(" rtr");
        }
        for b in self.data() {
            write!(f, " {b:02X}")?;
        }
        Ok(())
    }
}
