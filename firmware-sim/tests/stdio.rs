//! The `dips-firmware-sim` binary serves the protocol on stdin/stdout.

use std::io::Write;
use std::process::{Command, Stdio};

use dips_wire::*;

#[test]
fn binary_answers_hello_over_stdio() {
    let mut input = Vec::new();
    let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
    for (id, body) in [
        (1, ToKernel::Hello(Hello::current())),
        (2, ToKernel::ModelEnd),
    ] {
        input.extend_from_slice(
            encode_frame(
                &Frame {
                    request_id: id,
                    body,
                },
                &mut buf,
            )
            .unwrap(),
        );
    }
    input.extend([0xAB, 0x00]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_dips-firmware-sim"))
        .args(["--model-capacity-bytes", "4096"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&input).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut replies = Vec::new();
    let mut window = &out.stdout[..];
    while let Feed::Frame { payload, remaining } = acc.feed(window) {
        replies.push(decode_frame::<FromKernel>(payload).unwrap());
        window = remaining;
    }
    assert_eq!(replies.len(), 3);
    assert!(matches!(replies[0].body, FromKernel::HelloAck(_)));
    assert_eq!(
        replies[1].body,
        FromKernel::Error(WireError::Upload(UploadError::NotStarted))
    );
    assert_eq!(replies[2].body, FromKernel::Error(WireError::BadFrame));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("2 requests, 1 bad frames"), "{stderr}");
}

#[test]
fn binary_rejects_bad_arguments() {
    let out = Command::new(env!("CARGO_BIN_EXE_dips-firmware-sim"))
        .arg("--bogus")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--bogus"));
}
