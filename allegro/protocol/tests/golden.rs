//! Golden frames: a candump of a real V4 session (device id 0, quoted in a public python-can
//! driver), and frames derived by hand from the vendor drivers' arithmetic.

use dips_allegro_protocol::message::Request;
use dips_allegro_protocol::scale::{counts_to_radians, normalised_to_pwm, radians_to_counts};
use dips_allegro_protocol::{
    CanFrame, DecodeError, DeviceId, HandInfo, HandReply, HandType, HostCommand, Periods, Status,
};
use embedded_can::{Frame, Id, StandardId};

const D0: DeviceId = DeviceId::DEFAULT;

fn data(id: u16, bytes: &[u8]) -> CanFrame {
    CanFrame::new(StandardId::new(id).unwrap(), bytes).unwrap()
}

fn rtr(id: u16) -> CanFrame {
    CanFrame::new_remote(StandardId::new(id).unwrap(), 0).unwrap()
}

#[test]
fn the_real_sessions_pose_requests_and_replies() {
    for (finger, id) in [(0u8, 0x080), (1, 0x084), (2, 0x088), (3, 0x08C)] {
        let f: CanFrame = HostCommand::Request(Request::FingerPose(finger))
            .to_frame(D0)
            .unwrap();
        assert_eq!(f, rtr(id));
        assert_eq!(f.to_string(), format!("{id:03X} [0] rtr"));
        assert_eq!(
            HostCommand::from_frame(&f).unwrap(),
            (HostCommand::Request(Request::FingerPose(finger)), D0)
        );
    }
    let replies: [(u16, [u8; 8]); 4] = [
        (0x080, [0xCA, 0xFD, 0xBD, 0xFE, 0x90, 0xFF, 0xCE, 0xFF]),
        (0x084, [0xF9, 0xFF, 0xCF, 0xFE, 0x9A, 0xFF, 0xBE, 0xFF]),
        (0x088, [0x18, 0x00, 0xD3, 0xFE, 0xA7, 0xFF, 0xD6, 0xFF]),
        (0x08C, [0x34, 0x0A, 0xEF, 0xFF, 0xAF, 0x00, 0xFC, 0xFF]),
    ];
    let expected: [[i16; 4]; 4] = [
        [-566, -323, -112, -50],
        [-7, -305, -102, -66],
        [24, -301, -89, -42],
        [2612, -17, 175, -4],
    ];
    for (finger, ((id, bytes), counts)) in replies.iter().zip(expected).enumerate() {
        let f = data(*id, bytes);
        let (reply, device) = HandReply::from_frame(&f).unwrap();
        assert_eq!(device, D0);
        assert_eq!(
            reply,
            HandReply::FingerPose {
                finger: finger as u8,
                counts
            }
        );
        // And back to the same bytes.
        assert_eq!(reply.to_frame::<CanFrame>(D0).unwrap(), f);
    }
    // The thumb's roll: 2612 counts = 2612 × 333.3/65536 ° = 13.284° = 0.23185 rad.
    let thumb_roll = counts_to_radians(2612);
    assert!(
        (thumb_roll.to_degrees() - 13.284_0).abs() < 1e-3,
        "{thumb_roll}"
    );
    assert_eq!(radians_to_counts(thumb_roll), 2612);
}

#[test]
fn the_real_sessions_hand_info_temperatures_and_torques() {
    assert_eq!(
        HostCommand::Request(Request::HandInfo).to_frame::<CanFrame>(D0),
        Some(rtr(0x200))
    );
    let info = data(0x200, &[0x02, 0x04, 0x06, 0x04, 0x00, 0x3C, 0x05]);
    let (reply, _) = HandReply::from_frame(&info).unwrap();
    let HandReply::HandInfo(i) = reply else {
        panic!("{reply:?}")
    };
    assert_eq!(
        i,
        HandInfo {
            hardware_version: 0x0402,
            firmware_version: 0x0406,
            hand_type: HandType::Right,
            temperature_c: 60,
            status: Status(0x05),
        }
    );
    assert!(i.status.servo_on() && !i.status.high_temperature());
    assert!(i.status.internal_communication_fault());
    assert_eq!(reply.to_frame::<CanFrame>(D0).unwrap(), info);

    assert_eq!(
        HostCommand::Request(Request::Temperature(0)).to_frame::<CanFrame>(D0),
        Some(rtr(0x0E0))
    );
    let t = data(0x0E0, &[0x2B, 0x2A, 0x29, 0x25]);
    assert_eq!(
        HandReply::from_frame(&t).unwrap().0,
        HandReply::Temperature {
            finger: 0,
            celsius: [43, 42, 41, 37]
        }
    );

    let torque = data(0x180, &[0x02, 0x00, 0xCB, 0x00, 0x42, 0x00, 0x25, 0x00]);
    let cmd = HostCommand::SetTorque {
        finger: 0,
        pwm: [2, 203, 66, 37],
    };
    assert_eq!(cmd.to_frame::<CanFrame>(D0).unwrap(), torque);
    assert_eq!(torque.to_string(), "180 [8] 02 00 CB 00 42 00 25 00");
    assert_eq!(HostCommand::from_frame(&torque).unwrap(), (cmd, D0));
}

#[test]
fn start_up_and_shutdown_frames_from_the_drivers_arithmetic() {
    // SYSTEM_OFF = 0x41 << 2, no data; SYSTEM_ON = 0x40 << 2.
    assert_eq!(
        HostCommand::SystemOff.to_frame::<CanFrame>(D0),
        Some(data(0x104, &[]))
    );
    assert_eq!(
        HostCommand::SystemOn.to_frame::<CanFrame>(D0),
        Some(data(0x100, &[]))
    );
    // SET_PERIOD {3, 0, 0} ms = 0x81 << 2 with three little-endian u16.
    assert_eq!(
        HostCommand::SetPeriod(Periods::STREAM_POSES).to_frame::<CanFrame>(D0),
        Some(data(0x204, &[3, 0, 0, 0, 0, 0]))
    );
    assert_eq!(
        HostCommand::SetPeriod(Periods::STOPPED).to_frame::<CanFrame>(D0),
        Some(data(0x204, &[0; 6]))
    );
    assert_eq!(
        HostCommand::Request(Request::Serial).to_frame::<CanFrame>(D0),
        Some(rtr(0x220))
    );
    // The thumb's torques at device 1: 0x63 << 2 | 1 = 0x18D; −0.25 × 1200 = −300 = 0xFED4.
    let pwm = [
        normalised_to_pwm(-0.25),
        0,
        normalised_to_pwm(1.0),
        normalised_to_pwm(-3.0),
    ];
    let f: CanFrame = HostCommand::SetTorque { finger: 3, pwm }
        .to_frame(DeviceId::new(1).unwrap())
        .unwrap();
    assert_eq!(f, data(0x18D, &[0xD4, 0xFE, 0, 0, 0xB0, 0x04, 0x50, 0xFB]));
    let serial = data(0x220, b"SAH040C0");
    assert_eq!(
        HandReply::from_frame(&serial).unwrap().0,
        HandReply::Serial(*b"SAH040C0")
    );
}

#[test]
fn frames_outside_the_protocol_are_errors_never_panics() {
    let ext = CanFrame::new(embedded_can::ExtendedId::new(0x180).unwrap(), &[0; 8]).unwrap();
    assert_eq!(
        HandReply::from_frame(&ext),
        Err(DecodeError::ExtendedId(0x180))
    );
    assert_eq!(
        HandReply::from_frame(&data(0x7FC, &[1])),
        Err(DecodeError::UnknownCommand(0x1FF))
    );
    assert!(matches!(
        HandReply::from_frame(&data(0x080, &[1, 2, 3])),
        Err(DecodeError::BadLength {
            expected: 8,
            got: 3,
            ..
        })
    ));
    assert!(matches!(
        HandReply::from_frame(&rtr(0x080)),
        Err(DecodeError::WrongKind { remote: true, .. })
    ));
    assert!(matches!(
        HandReply::from_frame(&data(0x180, &[0; 8])),
        Err(DecodeError::WrongDirection(_))
    ));
    assert!(matches!(
        HostCommand::from_frame(&data(0x200, &[0; 7])),
        Err(DecodeError::WrongKind { remote: false, .. })
    ));
    // Every identifier and every length decodes to a value or an error.
    for id in 0..0x800u16 {
        for len in 0..=8usize {
            let f = data(id, &[0xA5; 8][..len]);
            let _ = HandReply::from_frame(&f);
            let _ = HostCommand::from_frame(&f);
        }
        let _ = HostCommand::from_frame(&rtr(id));
        let _ = HandReply::from_frame(&rtr(id));
    }
    assert!(matches!(data(0x123, &[]).id(), Id::Standard(_)));
}
