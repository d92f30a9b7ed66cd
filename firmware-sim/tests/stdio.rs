//! The `dips-firmware-sim` binary serves the protocol on stdin/stdout.

mod common;

use std::io::Write;
use std::process::{Command, Stdio};

use common::frame_bytes;
use dips_wire::*;

#[test]
fn binary_answers_hello_over_stdio() {
    let mut input = Vec::new();
    for (id, body) in [
        (1, ToKernel::Hello(Hello::current())),
        (2, ToKernel::ModelEnd),
    ] {
        input.extend(frame_bytes(id, body));
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
fn binary_help_prints_the_options_and_succeeds() {
    for flag in ["--help", "-h"] {
        let out = Command::new(env!("CARGO_BIN_EXE_dips-firmware-sim"))
            .arg(flag)
            .output()
            .unwrap();
        assert!(out.status.success(), "{flag}: {:?}", out.status);
        let text = String::from_utf8_lossy(&out.stdout);
        for option in [
            "--listen",
            "--model-capacity-bytes",
            "--work-floats",
            "stdin",
        ] {
            assert!(text.contains(option), "{flag}: {option} missing in {text}");
        }
    }
}

#[test]
fn binary_serves_tcp_connections_one_after_another() {
    use std::io::{BufRead, BufReader, Read};
    use std::net::TcpStream;

    /// The child is killed however the test ends (a failed assertion must not leave a
    /// listening server behind).
    struct KillOnDrop(std::process::Child);
    impl Drop for KillOnDrop {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let mut child = KillOnDrop(
        Command::new(env!("CARGO_BIN_EXE_dips-firmware-sim"))
            .args([
                "--listen",
                "127.0.0.1:0",
                "--model-capacity-bytes",
                "8388608",
            ])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let mut stderr = BufReader::new(child.0.stderr.take().unwrap());
    let mut line = String::new();
    stderr.read_line(&mut line).unwrap();
    let addr = line
        .trim()
        .strip_prefix("listening on ")
        .expect(&line)
        .to_string();

    // A real (lowered) model: junk would be refused at its upload's end.
    let model = dips_onnx::lower_file(
        &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../onnx/tests/fixtures/torch-screwdriver-legacy/denoiser.onnx"),
        &dips_onnx::Expectation::new(dips_onnx::Role::Denoiser, "screwdriver"),
    )
    .unwrap()
    .blob;
    let exchange = |frames: Vec<(u32, ToKernel)>| -> Vec<Frame<FromKernel>> {
        let mut stream = TcpStream::connect(&addr).unwrap();
        let count = frames.len();
        for (id, body) in frames {
            stream.write_all(&frame_bytes(id, body)).unwrap();
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
        card_goals: Default::default(),
        first_modes: 0b1111,
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
    drop(child);
}

/// The binary, started as users start it, plans with models uploaded over stdio, exactly as
/// the library's firmware does in-process.
#[test]
fn binary_plans_with_models_uploaded_over_stdio() {
    use dips_firmware_sim::{FirmwareMemory, serve};
    use dips_onnx::{Expectation, Role, lower_file};

    let fixture = |file: &str, role| {
        let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../onnx/tests/fixtures/torch-screwdriver-legacy")
            .join(file);
        lower_file(&path, &Expectation::new(role, "screwdriver"))
            .unwrap()
            .blob
    };
    let den = fixture("denoiser.onnx", Role::Denoiser);
    let disc = fixture("discriminator.onnx", Role::Discriminator);
    let mut start = [0.1f32; 16];
    start[14] = 1.0;
    start[15] = 0.0;
    let mut requests = vec![ToKernel::Hello(Hello::current())];
    requests.extend(upload_messages(ModelRole::Denoiser, &den).unwrap());
    requests.extend(upload_messages(ModelRole::Discriminator, &disc).unwrap());
    requests.push(ToKernel::PlanRequest(PlanRequest {
        task: Task::Screwdriver,
        start_state: heapless::Vec::from_slice(&start).unwrap(),
        goal: -1.0,
        settings: SearchSettings {
            k: 4,
            node_budget: 2,
            seed: 3,
            ..SearchSettings::default()
        },
        previous_mode: Some(0),
        card_goals: Default::default(),
        first_modes: 0b111,
    }));
    let mut input = Vec::new();
    for (i, body) in requests.into_iter().enumerate() {
        input.extend(frame_bytes(i as u32, body));
    }
    let decode = |bytes: &[u8]| {
        let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
        let mut replies = Vec::new();
        let mut window = bytes;
        while let Feed::Frame { payload, remaining } = acc.feed(window) {
            replies.push(decode_frame::<FromKernel>(payload).unwrap().body);
            window = remaining;
        }
        replies
    };

    let mut child = Command::new(env!("CARGO_BIN_EXE_dips-firmware-sim"))
        .args(["--work-floats", "4000000"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let to_child = input.clone();
    let writer = std::thread::spawn(move || stdin.write_all(&to_child));
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let from_binary = decode(&out.stdout);

    let mut memory = FirmwareMemory::planning(4 << 20, 4_000_000);
    let mut firmware = memory.firmware();
    let mut in_process = Vec::new();
    serve(&mut firmware, &input[..], &mut in_process).unwrap();
    let in_process = decode(&in_process);

    assert_eq!(from_binary.len(), in_process.len());
    let plan = |replies: &[FromKernel]| match replies.last() {
        Some(FromKernel::PlanReply(r)) => {
            let mut r = r.clone();
            r.stats.elapsed_ms = 0;
            r
        }
        other => panic!("expected a plan reply, got {other:?}"),
    };
    let reply = plan(&from_binary);
    assert!(
        matches!(
            reply.status,
            PlanStatus::Found | PlanStatus::Approximate { .. }
        ),
        "{reply:?}"
    );
    assert!((1..=2).contains(&reply.stats.nodes_expanded), "{reply:?}");
    assert_eq!(reply, plan(&in_process));
}
