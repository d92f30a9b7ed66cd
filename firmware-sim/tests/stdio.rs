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

#[test]
fn binary_serves_tcp_connections_one_after_another() {
    use std::io::{BufRead, BufReader, Read};
    use std::net::TcpStream;

    let mut child = Command::new(env!("CARGO_BIN_EXE_dips-firmware-sim"))
        .args(["--listen", "127.0.0.1:0", "--model-capacity-bytes", "4096"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    stderr.read_line(&mut line).unwrap();
    let addr = line
        .trim()
        .strip_prefix("listening on ")
        .expect(&line)
        .to_string();

    let model = vec![3u8; 1500];
    let exchange = |frames: Vec<(u32, ToKernel)>| -> Vec<Frame<FromKernel>> {
        let mut stream = TcpStream::connect(&addr).unwrap();
        let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
        let count = frames.len();
        for (id, body) in frames {
            stream
                .write_all(
                    encode_frame(
                        &Frame {
                            request_id: id,
                            body,
                        },
                        &mut buf,
                    )
                    .unwrap(),
                )
                .unwrap();
        }
        let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
        let mut replies = Vec::new();
        let mut rx = [0u8; 256];
        while replies.len() < count {
            let n = stream.read(&mut rx).unwrap();
            assert!(n > 0, "connection closed early");
            let mut window = &rx[..n];
            while let Feed::Frame { payload, remaining } = acc.feed(window) {
                replies.push(decode_frame::<FromKernel>(payload).unwrap());
                window = remaining;
            }
        }
        replies
    };
    // First connection: handshake and upload the denoiser.
    let mut first = vec![(1, ToKernel::Hello(Hello::current()))];
    first.extend(
        upload_messages(ModelRole::Denoiser, &model)
            .unwrap()
            .enumerate()
            .map(|(i, m)| (10 + i as u32, m)),
    );
    let replies = exchange(first);
    assert!(matches!(
        replies.last().unwrap().body,
        FromKernel::ModelLoaded(_)
    ));
    // Second connection: a new session needs a new Hello; the denoiser is still loaded.
    let plan = ToKernel::PlanRequest(PlanRequest {
        task: Task::Card,
        start_state: heapless::Vec::from_slice(&[0.0; 12]).unwrap(),
        goal: -0.06,
        settings: SearchSettings::default(),
        previous_mode: None,
    });
    let replies = exchange(vec![
        (1, plan.clone()),
        (2, ToKernel::Hello(Hello::current())),
        (3, plan),
    ]);
    assert_eq!(
        replies[0].body,
        FromKernel::Error(WireError::HandshakeRequired)
    );
    assert_eq!(
        replies[2].body,
        FromKernel::Error(WireError::ModelNotLoaded {
            role: ModelRole::Discriminator
        })
    );
    child.kill().unwrap();
    child.wait().unwrap();
}
