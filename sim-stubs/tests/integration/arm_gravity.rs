//! The simulated arm's gravity load (`ferrobot_sim::arm::gravity_torques`) against a hand
//! calculation.

use ferrobot_sim::arm::gravity_torques;

#[test]
fn shoulder_load_matches_a_hand_calculation() {
    // At zero angles the upper arm stands vertical and the forearm points along +x. About
    // joint_2 (axis +y), gravity's torque is g · Σ m·x over the links it carries:
    // 0.21248·0.009598 + 0.18746·(0.05+0.11783) + 0.06059·(0.05+0.2002+0.04294)
    // + 0.12421·(0.05+0.2002+0.063+0.040623) = 0.09522 kg·m.
    let arm = ferrobot_sim::robots::by_name("locobot")
        .expect("locobot")
        .arm;
    let mut t = [0.0; 5];
    gravity_torques(&arm, &[0.0; 5], &mut t);
    assert!((t[1] - 0.09522 * 9.81).abs() < 1e-3, "{}", t[1]);
    // Yaw never carries gravity load; folding the forearm up (joint_3 = −π/2) shortens the
    // lever of joint_2.
    assert!(t[0].abs() < 1e-12);
    let mut folded = [0.0; 5];
    gravity_torques(
        &arm,
        &[0.0, 0.0, -std::f64::consts::FRAC_PI_2, 0.0, 0.0],
        &mut folded,
    );
    assert!(folded[1] < 0.3 * t[1], "{}", folded[1]);
}
