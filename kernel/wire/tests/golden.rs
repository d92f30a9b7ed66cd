//! Golden encodings: one canonical message per variant against committed bytes, and the
//! schema key. If one of these fails, the wire layout changed: if that was intended, describe
//! the change in `SCHEMA` (src/schema.rs), bump `PROTOCOL_VERSION` unless only variants were
//! appended, and update the bytes below.

mod common;

use common::encode;
use dips_wire::error::RequestField;
use dips_wire::*;
use heapless::Vec;

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn canonical_to_kernel() -> std::vec::Vec<ToKernel> {
    vec![
        ToKernel::Hello(Hello {
            protocol_version: 1,
            schema_key: 0x0123_4567_89ab_cdef,
        }),
        ToKernel::PlanRequest(PlanRequest {
            task: Task::Screwdriver,
            start_state: Vec::from_slice(&[0.5, -1.0, 0.0, 1.0]).unwrap(),
            goal: -core::f32::consts::FRAC_PI_3,
            settings: SearchSettings {
                seed: 42,
                // The golden bytes were written when the default budget was 10 000.
                node_budget: 10_000,
                ..SearchSettings::default()
            },
            previous_mode: Some(2),
            card_goals: Default::default(),
            first_modes: 0b111,
        }),
        ToKernel::ModelBegin(ModelBegin {
            role: ModelRole::Discriminator,
            total_len_bytes: 1000,
            crc32: 0xCBF4_3926,
        }),
        ToKernel::ModelChunk(ModelChunk {
            offset_bytes: 512,
            bytes: Vec::from_slice(&[0, 1, 2, 0xFF]).unwrap(),
        }),
        ToKernel::ModelEnd,
        ToKernel::SetPrior(PriorTable {
            task: Task::Screwdriver,
            probabilities: Vec::from_slice(&[
                1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 0.0, 0.5, 0.5, 0.5, 0.0,
            ])
            .unwrap(),
        }),
        ToKernel::SetSampler(SamplerSettings {
            method: SamplerMethod::Ddim { steps: 300 },
            guidance_weight: 1.2,
        }),
        ToKernel::Status,
        ToKernel::Cancel,
    ]
}

/// Appended sampler methods, in a `SetSampler` (the first entry is the protocol-1 original).
fn canonical_sampler_methods() -> std::vec::Vec<SamplerMethod> {
    vec![
        SamplerMethod::Ddpm { noise_factor: 0.5 },
        SamplerMethod::DdimEta {
            steps: 16,
            eta: 1.0,
        },
        SamplerMethod::DdpmStrided {
            steps: 16,
            noise_factor: 0.5,
        },
    ]
}

fn canonical_from_kernel() -> std::vec::Vec<FromKernel> {
    vec![
        FromKernel::HelloAck(HelloAck {
            protocol_version: 1,
            schema_key: 0x0123_4567_89ab_cdef,
            max_frame_len_bytes: 540,
            model_chunk_len_bytes: 512,
        }),
        FromKernel::PlanReply(PlanReply {
            modes: Vec::from_slice(&[2, 0, 1]).unwrap(),
            terminal_state: Vec::from_slice(&[0.25, -0.5]).unwrap(),
            status: PlanStatus::Approximate {
                reason: ApproximateReason::TimeBudget,
            },
            stats: PlanStats {
                nodes_expanded: 7,
                nodes_generated: 21,
                sampler_calls: 7,
                discriminator_calls: 7,
                elapsed_ms: 1234,
            },
        }),
        FromKernel::ModelAck(ModelAck {
            role: ModelRole::Denoiser,
            received_bytes: 512,
            total_len_bytes: 1000,
        }),
        FromKernel::ModelLoaded(ModelLoaded {
            role: ModelRole::Denoiser,
            len_bytes: 1000,
            crc32: 0xCBF4_3926,
        }),
        FromKernel::Error(WireError::VersionMismatch {
            kernel_version: 1,
            host_version: 2,
            kernel_schema_key: 3,
            host_schema_key: 4,
        }),
        FromKernel::Applied,
        FromKernel::Status(KernelStatus {
            denoiser: Some(ModelIdentity {
                len_bytes: 1000,
                crc32: 0xCBF4_3926,
                task: Some(Task::Card),
                horizon: 13,
                state_dim: 12,
                action_dim: 17,
                fingers: 2,
                diffusion_steps: 256,
            }),
            discriminator: None,
            memory: MemoryUse {
                model_capacity_bytes: 1 << 20,
                models_bytes: 1000,
                planner_bytes: 400_000,
                work_floats: 1 << 18,
                work_floats_used: 5000,
            },
            last_plan: Some(LastPlan {
                request_id: 3,
                status: PlanStatus::Approximate {
                    reason: ApproximateReason::Cancelled,
                },
                elapsed_ms: 250,
                nodes_expanded: 4,
                segments_sampled: 192,
                particles: 16,
                effective_particles: 12.5,
                expected_progress: -0.04,
                terminal_cost: 4.0e-4,
                cost_to_come: 120.0,
                heuristic: 4.0,
            }),
            frames: FrameCounts {
                requests: 10,
                bad_frames: 2,
                replies: 12,
                cancelled_plans: 1,
            },
        }),
    ]
}

/// Every `WireError` variant (errors are the kernel's main vocabulary, so pin them all).
fn canonical_errors() -> std::vec::Vec<WireError> {
    vec![
        WireError::BadFrame,
        WireError::TooLong {
            len_bytes: 2000,
            max_bytes: 540,
        },
        WireError::DecodeFailed,
        WireError::UnknownRequest { tag: 9 },
        WireError::VersionMismatch {
            kernel_version: 1,
            host_version: 2,
            kernel_schema_key: 3,
            host_schema_key: 4,
        },
        WireError::HandshakeRequired,
        WireError::Busy,
        WireError::Upload(UploadError::CrcMismatch {
            expected_crc32: 1,
            computed_crc32: 2,
        }),
        WireError::ModelNotLoaded {
            role: ModelRole::Discriminator,
        },
        WireError::PlannerUnavailable,
        WireError::InvalidRequest {
            field: RequestField::PreviousMode,
        },
        WireError::InvalidRequest {
            field: RequestField::Sampler,
        },
        WireError::ModelRejected {
            role: ModelRole::Denoiser,
            fault: ModelFault::TooLarge {
                needed_floats: 300,
                capacity_floats: 2,
            },
        },
    ]
}

const GOLDEN_TO_KERNEL: [&str; 9] = [
    "02070b01ef9bafcdf8acd1910100",
    "03070102040101023f010380bf01010101010d803f920a86bf10076666663f04401c46010d7a44cdcccc3d904ee0a7122a01050102010700",
    "0b070201e807a6f2d0df0c00",
    "060703800404040102ff00",
    "03070400",
    "030705020c0103803f0101010101010101010101010101023f0101023f0101023f010101010101023f0101023f0101023f0101010100",
    "0a070601ac029a99993f00",
    "03070700",
    "03070800",
];
const GOLDEN_FROM_KERNEL: [&str; 7] = [
    "02070f01ef9bafcdf8acd191019c04800400",
    "05070103020301020103803e01010abf010107150707d20900",
    "030702058004e80700",
    "03070308e807a6f2d0df0c00",
    "080704040102030400",
    "03070500",
    "13070601e807a6f2d0df0c01010d0c1102800218808040e80780b518808010882701030106fa0104c00110010b48410ad723bd17b7d1390103f042010780400a020c0100",
];
const GOLDEN_ERRORS: [&str; 13] = [
    "0307040100",
    "08070401d00f9c0400",
    "0407040200",
    "050704030900",
    "080704040102030400",
    "0407040500",
    "0407040600",
    "0707040705010200",
    "050704080100",
    "0407040900",
    "0507040a0300",
    "0507040a0500",
    "0407040b0502ac020200",
];
const GOLDEN_SCHEMA_KEY: u64 = 0xdce2_3497_e44c_66c6;

#[test]
fn schema_key_is_pinned() {
    assert_eq!(SCHEMA_KEY, GOLDEN_SCHEMA_KEY, "actual {SCHEMA_KEY:#018x}");
    assert_eq!(PROTOCOL_VERSION, 3);
}

#[test]
fn to_kernel_golden_bytes() {
    let msgs = canonical_to_kernel();
    assert_eq!(msgs.len() as u32, <ToKernel as Message>::VARIANT_COUNT);
    let actual: std::vec::Vec<String> = msgs.into_iter().map(|m| hex(&encode(7, m))).collect();
    assert_eq!(actual, GOLDEN_TO_KERNEL, "actual: {actual:#?}");
}

#[test]
fn from_kernel_golden_bytes() {
    let msgs = canonical_from_kernel();
    assert_eq!(msgs.len() as u32, <FromKernel as Message>::VARIANT_COUNT);
    let actual: std::vec::Vec<String> = msgs.into_iter().map(|m| hex(&encode(7, m))).collect();
    assert_eq!(actual, GOLDEN_FROM_KERNEL, "actual: {actual:#?}");
}

#[test]
fn wire_error_golden_bytes() {
    let actual: std::vec::Vec<String> = canonical_errors()
        .into_iter()
        .map(|e| hex(&encode(7, FromKernel::Error(e))))
        .collect();
    assert_eq!(actual, GOLDEN_ERRORS, "actual: {actual:#?}");
}

/// Every `PlanStatus` variant and every `ApproximateReason`, in a minimal reply (statuses are
/// how the kernel reports the outcome of planning, so pin them all). The first nine entries
/// are the protocol-1 originals; the rest were appended by the kernel-wire integration.
fn canonical_statuses() -> std::vec::Vec<PlanStatus> {
    let approx = |reason| PlanStatus::Approximate { reason };
    vec![
        PlanStatus::Found,
        approx(ApproximateReason::NodeBudget),
        approx(ApproximateReason::TimeBudget),
        approx(ApproximateReason::Exhausted),
        PlanStatus::NoPlan,
        PlanStatus::InvalidStart,
        PlanStatus::InvalidGoal,
        PlanStatus::Cancelled,
        approx(ApproximateReason::Capacity {
            capacity: PlanCapacity::OpenList,
        }),
        approx(ApproximateReason::SamplerFailed),
        approx(ApproximateReason::ScorerFailed),
        PlanStatus::InvalidSettings {
            field: SettingsField::PMin,
        },
        PlanStatus::InvalidProblem,
        PlanStatus::CapacityExceeded {
            capacity: PlanCapacity::Modes,
        },
        approx(ApproximateReason::Cancelled),
    ]
}

const GOLDEN_STATUSES: [&str; 15] = [
    "030701010101010101010100",
    "03070101020101010101010100",
    "03070101030101010101010100",
    "03070101030102010101010100",
    "030701010202010101010100",
    "030701010203010101010100",
    "030701010204010101010100",
    "030701010205010101010100",
    "0307010104010302010101010100",
    "03070101030104010101010100",
    "03070101030105010101010100",
    "03070101030605010101010100",
    "030701010207010101010100",
    "03070101030805010101010100",
    "03070101030106010101010100",
];

#[test]
fn plan_status_golden_bytes() {
    let actual: std::vec::Vec<String> = canonical_statuses()
        .into_iter()
        .map(|status| {
            let reply = PlanReply {
                modes: Vec::new(),
                terminal_state: Vec::new(),
                status,
                stats: PlanStats::default(),
            };
            hex(&encode(7, FromKernel::PlanReply(reply)))
        })
        .collect();
    assert_eq!(actual, GOLDEN_STATUSES, "actual: {actual:#?}");
}

const GOLDEN_SAMPLER_METHODS: [&str; 3] = [
    "030706010101063f9a99993f00",
    "05070602100107803f9a99993f00",
    "05070603100101063f9a99993f00",
];

#[test]
fn sampler_method_golden_bytes() {
    let actual: std::vec::Vec<String> = canonical_sampler_methods()
        .into_iter()
        .map(|method| {
            hex(&encode(
                7,
                ToKernel::SetSampler(SamplerSettings {
                    method,
                    guidance_weight: 1.2,
                }),
            ))
        })
        .collect();
    assert_eq!(actual, GOLDEN_SAMPLER_METHODS, "actual: {actual:#?}");
}

#[test]
fn golden_frames_decode_back() {
    for m in canonical_to_kernel() {
        let bytes = encode(7, m.clone());
        assert_eq!(
            common::deframe::<ToKernel>(&bytes, &[bytes.len()]),
            vec![Ok(Frame {
                request_id: 7,
                body: m
            })]
        );
    }
    for m in canonical_from_kernel() {
        let bytes = encode(7, m.clone());
        assert_eq!(
            common::deframe::<FromKernel>(&bytes, &[bytes.len()]),
            vec![Ok(Frame {
                request_id: 7,
                body: m
            })]
        );
    }
}
