//! proptest strategies for every message type.
#![allow(dead_code, unreachable_pub)]

use dips_wire::error::RequestField;
use dips_wire::*;
use heapless::Vec;
use proptest::prelude::*;

pub fn finite_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        -1.0e6f32..1.0e6f32,
        Just(0.0f32),
        Just(-0.0f32),
        Just(f32::MAX)
    ]
}

pub fn f32_vec<const N: usize>() -> impl Strategy<Value = Vec<f32, N>> {
    proptest::collection::vec(finite_f32(), 0..=N)
        .prop_map(|v| Vec::from_slice(&v).expect("bounded by N"))
}

pub fn task() -> impl Strategy<Value = Task> {
    prop_oneof![Just(Task::Screwdriver), Just(Task::Card)]
}

pub fn role() -> impl Strategy<Value = ModelRole> {
    prop_oneof![Just(ModelRole::Denoiser), Just(ModelRole::Discriminator)]
}

prop_compose! {
    pub fn settings()(
        k in any::<u16>(), max_depth in any::<u8>(),
        floats in proptest::array::uniform4(finite_f32()),
        node_budget in any::<u32>(), time_budget_ms in any::<u32>(), seed in any::<u64>(),
        last in any::<bool>(), ml in any::<bool>(),
    ) -> SearchSettings {
        SearchSettings {
            k, max_depth, gamma: floats[0], alpha: floats[1], beta: floats[2], p_min: floats[3],
            node_budget, time_budget_ms, seed,
            cost_to_come: if last { CostToCome::LastSegment } else { CostToCome::Cumulative },
            variant: if ml { SearchVariant::MaxLikelihood } else { SearchVariant::Particles },
        }
    }
}

prop_compose! {
    pub fn plan_request()(
        task in task(), start_state in f32_vec::<MAX_STATE_DIM>(), goal in finite_f32(),
        settings in settings(), previous_mode in any::<Option<u8>>(), paper in any::<bool>(),
        first_modes in any::<u8>(),
    ) -> PlanRequest {
        let card_goals = if paper { CardGoals::Paper } else { CardGoals::Capped };
        PlanRequest { task, start_state, goal, settings, previous_mode, card_goals, first_modes }
    }
}

pub fn plan_status() -> impl Strategy<Value = PlanStatus> {
    prop_oneof![
        Just(PlanStatus::Found),
        Just(PlanStatus::Approximate {
            reason: ApproximateReason::NodeBudget
        }),
        Just(PlanStatus::Approximate {
            reason: ApproximateReason::TimeBudget
        }),
        Just(PlanStatus::Approximate {
            reason: ApproximateReason::Exhausted
        }),
        Just(PlanStatus::NoPlan),
        Just(PlanStatus::InvalidStart),
        Just(PlanStatus::InvalidGoal),
        Just(PlanStatus::Cancelled),
        approximate_extra(),
        settings_field().prop_map(|field| PlanStatus::InvalidSettings { field }),
        Just(PlanStatus::InvalidProblem),
        plan_capacity().prop_map(|capacity| PlanStatus::CapacityExceeded { capacity }),
    ]
}

/// The approximate reasons appended after the first three.
pub fn approximate_extra() -> impl Strategy<Value = PlanStatus> {
    prop_oneof![
        plan_capacity().prop_map(|capacity| ApproximateReason::Capacity { capacity }),
        Just(ApproximateReason::SamplerFailed),
        Just(ApproximateReason::ScorerFailed),
        Just(ApproximateReason::Cancelled),
    ]
    .prop_map(|reason| PlanStatus::Approximate { reason })
}

pub fn plan_capacity() -> impl Strategy<Value = PlanCapacity> {
    prop_oneof![
        Just(PlanCapacity::Particles),
        Just(PlanCapacity::Nodes),
        Just(PlanCapacity::OpenList),
        Just(PlanCapacity::StateDim),
        Just(PlanCapacity::SegmentFloats),
        Just(PlanCapacity::Modes),
    ]
}

pub fn settings_field() -> impl Strategy<Value = SettingsField> {
    prop_oneof![
        Just(SettingsField::K),
        Just(SettingsField::MaxDepth),
        Just(SettingsField::Gamma),
        Just(SettingsField::Alpha),
        Just(SettingsField::Beta),
        Just(SettingsField::PMin),
    ]
}

prop_compose! {
    pub fn plan_reply()(
        modes in proptest::collection::vec(any::<u8>(), 0..=MAX_PLAN_MODES),
        terminal_state in f32_vec::<MAX_STATE_DIM>(), status in plan_status(),
        s in any::<[u32; 5]>(),
    ) -> PlanReply {
        PlanReply {
            modes: Vec::from_slice(&modes).expect("bounded"),
            terminal_state, status,
            stats: PlanStats {
                nodes_expanded: s[0], nodes_generated: s[1], sampler_calls: s[2],
                discriminator_calls: s[3], elapsed_ms: s[4],
            },
        }
    }
}

pub fn upload_error() -> impl Strategy<Value = UploadError> {
    (any::<u32>(), any::<u32>(), 0u8..6).prop_map(|(a, b, which)| match which {
        0 => UploadError::NotStarted,
        1 => UploadError::TooLarge {
            total_len_bytes: a,
            capacity_bytes: b,
        },
        2 => UploadError::BadOffset {
            expected_offset_bytes: a,
            got_offset_bytes: b,
        },
        3 => UploadError::Overflow {
            end_offset_bytes: a,
            total_len_bytes: b,
        },
        4 => UploadError::Incomplete {
            received_bytes: a,
            total_len_bytes: b,
        },
        _ => UploadError::CrcMismatch {
            expected_crc32: a,
            computed_crc32: b,
        },
    })
}

pub fn wire_error() -> impl Strategy<Value = WireError> {
    (
        any::<u32>(),
        any::<u32>(),
        any::<u16>(),
        any::<u64>(),
        upload_error(),
        role(),
        0u8..12,
    )
        .prop_map(|(a, b, v, key, upload, role, which)| match which {
            0 => WireError::BadFrame,
            1 => WireError::TooLong {
                len_bytes: a,
                max_bytes: b,
            },
            2 => WireError::DecodeFailed,
            3 => WireError::UnknownRequest { tag: a },
            4 => WireError::VersionMismatch {
                kernel_version: v,
                host_version: v.wrapping_add(1),
                kernel_schema_key: key,
                host_schema_key: !key,
            },
            5 => WireError::HandshakeRequired,
            6 => WireError::Busy,
            7 => WireError::Upload(upload),
            8 => WireError::ModelNotLoaded { role },
            9 => WireError::PlannerUnavailable,
            10 => WireError::InvalidRequest {
                field: [
                    RequestField::StartState,
                    RequestField::Goal,
                    RequestField::Settings,
                    RequestField::PreviousMode,
                    RequestField::Prior,
                    RequestField::Sampler,
                ][(a % 6) as usize],
            },
            _ => WireError::ModelRejected {
                role,
                fault: match a % 3 {
                    0 => ModelFault::Invalid,
                    1 => ModelFault::WrongShape,
                    _ => ModelFault::TooLarge {
                        needed_floats: a,
                        capacity_floats: b,
                    },
                },
            },
        })
}

pub fn to_kernel() -> impl Strategy<Value = ToKernel> {
    prop_oneof![
        (any::<u16>(), any::<u64>()).prop_map(|(protocol_version, schema_key)| {
            ToKernel::Hello(Hello {
                protocol_version,
                schema_key,
            })
        }),
        plan_request().prop_map(ToKernel::PlanRequest),
        (role(), any::<u32>(), any::<u32>()).prop_map(|(role, total_len_bytes, crc32)| {
            ToKernel::ModelBegin(ModelBegin {
                role,
                total_len_bytes,
                crc32,
            })
        }),
        (
            any::<u32>(),
            proptest::collection::vec(any::<u8>(), 0..=MODEL_CHUNK_LEN)
        )
            .prop_map(|(offset_bytes, bytes)| ToKernel::ModelChunk(ModelChunk {
                offset_bytes,
                bytes: Vec::from_slice(&bytes).expect("bounded"),
            })),
        Just(ToKernel::ModelEnd),
        (task(), f32_vec::<MAX_PRIOR_FLOATS>()).prop_map(|(task, probabilities)| {
            ToKernel::SetPrior(PriorTable {
                task,
                probabilities,
            })
        }),
        (0u8..4, finite_f32(), any::<u16>(), finite_f32()).prop_map(
            |(kind, x, steps, guidance_weight)| {
                ToKernel::SetSampler(SamplerSettings {
                    method: match kind {
                        0 => SamplerMethod::Ddpm { noise_factor: x },
                        1 => SamplerMethod::Ddim { steps },
                        2 => SamplerMethod::DdimEta { steps, eta: x },
                        _ => SamplerMethod::DdpmStrided {
                            steps,
                            noise_factor: x,
                        },
                    },
                    guidance_weight,
                })
            }
        ),
        Just(ToKernel::Status),
        Just(ToKernel::Cancel),
    ]
}

pub fn model_identity() -> impl Strategy<Value = ModelIdentity> {
    (
        any::<u32>(),
        any::<u32>(),
        proptest::option::of(task()),
        any::<[u16; 5]>(),
    )
        .prop_map(|(len_bytes, crc32, task, d)| ModelIdentity {
            len_bytes,
            crc32,
            task,
            horizon: d[0],
            state_dim: d[1],
            action_dim: d[2],
            fingers: d[3],
            diffusion_steps: d[4],
        })
}

pub fn kernel_status() -> impl Strategy<Value = KernelStatus> {
    (
        proptest::option::of(model_identity()),
        proptest::option::of(model_identity()),
        any::<[u32; 5]>(),
        proptest::option::of((
            any::<[u32; 4]>(),
            plan_status(),
            any::<u8>(),
            proptest::array::uniform5(finite_f32()),
        )),
        any::<[u32; 4]>(),
    )
        .prop_map(|(denoiser, discriminator, m, last, f)| KernelStatus {
            denoiser,
            discriminator,
            memory: MemoryUse {
                model_capacity_bytes: m[0],
                models_bytes: m[1],
                planner_bytes: m[2],
                work_floats: m[3],
                work_floats_used: m[4],
            },
            last_plan: last.map(|(n, status, particles, x)| LastPlan {
                request_id: n[0],
                status,
                elapsed_ms: n[1],
                nodes_expanded: n[2],
                segments_sampled: n[3],
                particles,
                effective_particles: x[0],
                expected_progress: x[1],
                terminal_cost: x[2],
                cost_to_come: x[3],
                heuristic: x[4],
            }),
            frames: FrameCounts {
                requests: f[0],
                bad_frames: f[1],
                replies: f[2],
                cancelled_plans: f[3],
            },
        })
}

pub fn from_kernel() -> impl Strategy<Value = FromKernel> {
    prop_oneof![
        (any::<u16>(), any::<u64>(), any::<u32>(), any::<u32>()).prop_map(|(v, k, m, c)| {
            FromKernel::HelloAck(HelloAck {
                protocol_version: v,
                schema_key: k,
                max_frame_len_bytes: m,
                model_chunk_len_bytes: c,
            })
        }),
        plan_reply().prop_map(FromKernel::PlanReply),
        (role(), any::<u32>(), any::<u32>()).prop_map(|(role, received_bytes, total_len_bytes)| {
            FromKernel::ModelAck(ModelAck {
                role,
                received_bytes,
                total_len_bytes,
            })
        }),
        (role(), any::<u32>(), any::<u32>()).prop_map(|(role, len_bytes, crc32)| {
            FromKernel::ModelLoaded(ModelLoaded {
                role,
                len_bytes,
                crc32,
            })
        }),
        wire_error().prop_map(FromKernel::Error),
        Just(FromKernel::Applied),
        kernel_status().prop_map(FromKernel::Status),
    ]
}

/// Encode a frame into a fresh buffer of the maximum size.
pub fn encode<B: serde::Serialize>(request_id: u32, body: B) -> std::vec::Vec<u8> {
    let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
    encode_frame(&Frame { request_id, body }, &mut buf)
        .expect("every message fits MAX_ENCODED_FRAME_LEN")
        .to_vec()
}

/// Feed `stream` through an accumulator in the given chunk sizes; collect every outcome.
pub fn deframe<M: Message>(
    stream: &[u8],
    chunk_sizes: &[usize],
) -> std::vec::Vec<Result<Frame<M>, WireError>> {
    let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
    let mut out = std::vec::Vec::new();
    let mut rest = stream;
    let mut sizes = chunk_sizes.iter().cycle();
    while !rest.is_empty() {
        let n = sizes
            .next()
            .copied()
            .unwrap_or(rest.len())
            .clamp(1, rest.len());
        let (mut window, tail) = rest.split_at(n);
        rest = tail;
        loop {
            match acc.feed(window) {
                Feed::Consumed => break,
                Feed::Frame { payload, remaining } => {
                    out.push(decode_frame::<M>(payload).map_err(|e| e.error));
                    window = remaining;
                }
                Feed::Error { error, remaining } => {
                    out.push(Err(error));
                    window = remaining;
                }
            }
        }
    }
    out
}
