//! Protocol version and schema key exchanged in the `Hello` handshake.
//!
//! postcard is not self-describing, so a peer built from a different message layout would
//! misread bytes silently. [`SCHEMA_KEY`] is a 64-bit FNV-1a hash of [`SCHEMA`], a compact
//! description of every type's encoded layout. The golden-bytes tests in `tests/golden.rs`
//! pin both the canonical encodings and this key: a layout change breaks the golden bytes,
//! and whoever updates them must describe the change in [`SCHEMA`], which changes the key.

/// Wire protocol version; bump it for any change that is not an appended variant.
pub const PROTOCOL_VERSION: u16 = 3;

/// The message layout this crate encodes, as text (field order is encoding order).
pub const SCHEMA: &str = "\
Frame<B>{request_id:u32,body:B};\
ToKernel{0:Hello,1:PlanRequest,2:ModelBegin,3:ModelChunk,4:ModelEnd,5:SetPrior(PriorTable),6:SetSampler(SamplerSettings),7:Status,8:Cancel};\
FromKernel{0:HelloAck,1:PlanReply,2:ModelAck,3:ModelLoaded,4:Error(WireError),5:Applied,6:Status(KernelStatus)};\
Hello{protocol_version:u16,schema_key:u64};\
HelloAck{protocol_version:u16,schema_key:u64,max_frame_len_bytes:u32,model_chunk_len_bytes:u32};\
Task{0:Screwdriver,1:Card};\
PlanRequest{task:Task,start_state:Vec<f32,16>,goal:f32,settings:SearchSettings,previous_mode:Option<u8>,card_goals:CardGoals,first_modes:u8};\
CardGoals{0:Paper,1:Capped};\
SearchSettings{k:u16,max_depth:u8,gamma:f32,alpha:f32,beta:f32,p_min:f32,node_budget:u32,time_budget_ms:u32,seed:u64,cost_to_come:CostToCome,variant:SearchVariant};\
CostToCome{0:Cumulative,1:LastSegment};SearchVariant{0:Particles,1:MaxLikelihood};\
PlanReply{modes:Vec<u8,16>,terminal_state:Vec<f32,16>,status:PlanStatus,stats:PlanStats};\
PlanStatus{0:Found,1:Approximate{reason:ApproximateReason},2:NoPlan,3:InvalidStart,4:InvalidGoal,5:Cancelled,\
6:InvalidSettings{field:SettingsField},7:InvalidProblem,8:CapacityExceeded{capacity:PlanCapacity}};\
ApproximateReason{0:NodeBudget,1:TimeBudget,2:Exhausted,3:Capacity{capacity:PlanCapacity},4:SamplerFailed,5:ScorerFailed,6:Cancelled};\
PlanCapacity{0:Particles,1:Nodes,2:OpenList,3:StateDim,4:SegmentFloats,5:Modes};\
SettingsField{0:K,1:MaxDepth,2:Gamma,3:Alpha,4:Beta,5:PMin};\
PlanStats{nodes_expanded:u32,nodes_generated:u32,sampler_calls:u32,discriminator_calls:u32,elapsed_ms:u32};\
ModelRole{0:Denoiser,1:Discriminator};\
ModelBegin{role:ModelRole,total_len_bytes:u32,crc32:u32};\
ModelChunk{offset_bytes:u32,bytes:Vec<u8,512>};\
ModelAck{role:ModelRole,received_bytes:u32,total_len_bytes:u32};\
ModelLoaded{role:ModelRole,len_bytes:u32,crc32:u32};\
WireError{0:BadFrame,1:TooLong{len_bytes:u32,max_bytes:u32},2:DecodeFailed,3:UnknownRequest{tag:u32},\
4:VersionMismatch{kernel_version:u16,host_version:u16,kernel_schema_key:u64,host_schema_key:u64},\
5:HandshakeRequired,6:Busy,7:Upload(UploadError),8:ModelNotLoaded{role:ModelRole},9:PlannerUnavailable,\
10:InvalidRequest{field:RequestField},11:ModelRejected{role:ModelRole,fault:ModelFault}};\
ModelFault{0:Invalid,1:WrongShape,2:TooLarge{needed_floats:u32,capacity_floats:u32}};\
RequestField{0:StartState,1:Goal,2:Settings,3:PreviousMode,4:Prior,5:Sampler,6:FirstModes};\
PriorTable{task:Task,probabilities:Vec<f32,20>};\
SamplerMethod{0:Ddpm{noise_factor:f32},1:Ddim{steps:u16},2:DdimEta{steps:u16,eta:f32},3:DdpmStrided{steps:u16,noise_factor:f32}};SamplerSettings{method:SamplerMethod,guidance_weight:f32};\
UploadError{0:NotStarted,1:TooLarge{total_len_bytes:u32,capacity_bytes:u32},\
2:BadOffset{expected_offset_bytes:u32,got_offset_bytes:u32},3:Overflow{end_offset_bytes:u32,total_len_bytes:u32},\
4:Incomplete{received_bytes:u32,total_len_bytes:u32},5:CrcMismatch{expected_crc32:u32,computed_crc32:u32}};\
KernelStatus{denoiser:Option<ModelIdentity>,discriminator:Option<ModelIdentity>,memory:MemoryUse,last_plan:Option<LastPlan>,frames:FrameCounts};\
ModelIdentity{len_bytes:u32,crc32:u32,task:Option<Task>,horizon:u16,state_dim:u16,action_dim:u16,fingers:u16,diffusion_steps:u16};\
MemoryUse{model_capacity_bytes:u32,models_bytes:u32,planner_bytes:u32,work_floats:u32,work_floats_used:u32};\
LastPlan{request_id:u32,status:PlanStatus,elapsed_ms:u32,nodes_expanded:u32,segments_sampled:u32,particles:u8,effective_particles:f32,\
expected_progress:f32,terminal_cost:f32,cost_to_come:f32,heuristic:f32};\
FrameCounts{requests:u32,bad_frames:u32,replies:u32,cancelled_plans:u32}";

/// 64-bit FNV-1a hash of [`SCHEMA`]: equal keys mean equal message layouts.
pub const SCHEMA_KEY: u64 = fnv1a_64(SCHEMA.as_bytes());

/// 64-bit FNV-1a (offset basis `0xcbf29ce484222325`, prime `0x100000001b3`).
pub const fn fnv1a_64(bytes: &[u8]) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let mut i = 0;
    while i < bytes.len() {
        hash ^= bytes[i] as u64;
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
        i += 1;
    }
    hash
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_reference_values() {
        assert_eq!(fnv1a_64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a_64(b"a"), 0xaf63_dc4c_8601_ec8c);
    }
}
