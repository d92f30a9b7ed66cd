//! Physical units of the hand that the protocol does not carry: what a PWM value means in
//! N·m, the figure the emulator's joint model and the gravity compensation need.

/// Joint torque (N·m) at full-scale PWM (1200 at 12 V): the Allegro V4's stated maximum
/// joint torque, 0.7 N·m. The hand has no torque sensing, so this is the one bridge between
/// the vendor's PWM gains and physics; `docs/allegro.md` says what follows from it.
pub const FULL_SCALE_TORQUE_NM: f64 = 0.7;

/// N·m of a PWM value.
pub fn pwm_to_newton_metres(pwm: i16) -> f64 {
    dips_allegro_protocol::scale::pwm_to_normalised(pwm) * FULL_SCALE_TORQUE_NM
}

/// PWM per N·m: 1200 / 0.7.
pub const PWM_PER_NEWTON_METRE: f64 =
    dips_allegro_protocol::scale::FULL_SCALE_PWM as f64 / FULL_SCALE_TORQUE_NM;
