//! Forward kinematics of `models/loki.urdf` checked against an independent computation: plain 4x4
//! homogeneous matrices built from cos/sin, with the numbers copied by hand from the URDF (not read
//! from it), multiplied in the order the URDF joint tree gives. Agreement to 1e-9 m / 1e-9.

#![allow(clippy::unwrap_used)] // tests may unwrap (STYLE: no unwrap outside tests)

use nalgebra::Matrix4;
use robot_model::RobotModel;

fn trans(x: f64, y: f64, z: f64) -> Matrix4<f64> {
    Matrix4::new(
        1.0, 0.0, 0.0, x, 0.0, 1.0, 0.0, y, 0.0, 0.0, 1.0, z, 0.0, 0.0, 0.0, 1.0,
    )
}
fn rx(a: f64) -> Matrix4<f64> {
    let (s, c) = a.sin_cos();
    Matrix4::new(
        1.0, 0.0, 0.0, 0.0, 0.0, c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0,
    )
}
fn ry(a: f64) -> Matrix4<f64> {
    let (s, c) = a.sin_cos();
    Matrix4::new(
        c, 0.0, s, 0.0, 0.0, 1.0, 0.0, 0.0, -s, 0.0, c, 0.0, 0.0, 0.0, 0.0, 1.0,
    )
}
fn rz(a: f64) -> Matrix4<f64> {
    let (s, c) = a.sin_cos();
    Matrix4::new(
        c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    )
}

fn loki() -> RobotModel {
    RobotModel::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))
    .unwrap()
}

fn assert_close(name: &str, got: &Matrix4<f64>, want: &Matrix4<f64>) {
    let err = (got - want).abs().max();
    assert!(
        err < 1e-9,
        "{name}: max abs error {err:e}\n got {got}\nwant {want}"
    );
}

/// Hand-written left arm, 13 joints, base_footprint -> left_fingertip.
fn left_arm_13(q: &[f64; 13]) -> Matrix4<f64> {
    rz(q[0])                          // base_yaw, axis z, origin 0
        * trans(q[1], 0.0, 0.0)       // base_forward, prismatic x
        * trans(-0.15, 0.0, 0.40)     // spine_fixed
        * trans(0.0, 0.0, 0.50)       // torso_fixed
        * trans(0.05, 0.22, 0.35) * ry(q[2]) // left_shoulder_pitch
        * rx(q[3])                    // left_shoulder_roll
        * rz(q[4])                    // left_shoulder_yaw
        * trans(0.0, 0.0, -0.28) * ry(q[5]) // left_elbow
        * trans(0.0, 0.0, -0.05) * rz(q[6]) // left_forearm_roll
        * trans(0.0, 0.0, -0.22) * ry(q[7]) // left_wrist_pitch
        * rx(q[8])                    // left_wrist_roll
        * trans(0.0, 0.0, -0.10) * rx(q[9]) // left_finger_spread
        * ry(q[10])                   // left_finger_proximal_joint
        * trans(0.0, 0.0, -0.045) * ry(q[11]) // left_finger_middle_joint
        * trans(0.0, 0.0, -0.03) * ry(q[12])  // left_finger_distal_joint
        * trans(0.0, 0.0, -0.025) // left_fingertip_fixed
}

/// Hand-written right arm, 4 joints, torso -> right_wrist_center.
fn right_arm_4(q: &[f64; 4]) -> Matrix4<f64> {
    trans(0.05, -0.22, 0.35)
        * ry(q[0])
        * rx(q[1])
        * rz(q[2])
        * trans(0.0, 0.0, -0.28)
        * ry(q[3])
        * trans(0.0, 0.0, -0.27) // right_wrist_center_fixed on the elbow link
}

/// Hand-written neck, torso -> head_rgbd_optical_frame.
fn neck(q: &[f64; 4]) -> Matrix4<f64> {
    // rpy = (-pi/2, 0, -pi/2): R = Rz(-pi/2) Rx(-pi/2), written out: optical z = link x, etc.
    let optical = Matrix4::new(
        0.0, 0.0, 1.0, 0.0, //
        -1.0, 0.0, 0.0, 0.0, //
        0.0, -1.0, 0.0, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    );
    trans(0.05, 0.0, 0.42) * rz(q[0]) // neck_rotation
        * trans(0.0, 0.0, 0.06) * ry(q[1]) // neck_pitch
        * rx(q[2])                    // neck_roll
        * rz(q[3])                    // neck_yaw
        * trans(0.10, 0.0, 0.17)      // head_rgbd_fixed
        * optical // head_rgbd_optical_fixed
}

#[test]
fn left_arm_13_matches_hand_derived_transforms() {
    let m = loki();
    let chain = m.body_part("left_arm_13").unwrap();
    let configs: [[f64; 13]; 4] = [
        [0.0; 13],
        [
            0.3, 0.5, -1.2, 0.4, 0.7, -1.1, 0.9, 0.3, -0.5, 0.2, -0.8, -0.6, -0.4,
        ],
        [
            -2.0, -1.5, 0.8, 2.1, -1.9, -2.3, -2.4, -0.7, 0.75, -0.3, 0.1, -1.6, -1.4,
        ],
        [
            1.0, 0.1, -3.0, -0.2, 1.5, -0.1, 2.0, 0.6, 0.1, 0.35, -1.5, -0.2, -1.0,
        ],
    ];
    for q in &configs {
        let got = chain.fk(q).unwrap().to_homogeneous();
        assert_close("left_arm_13", &got, &left_arm_13(q));
    }
    // All zeros, written out: fingertip straight below the shoulder.
    let zero = chain.fk(&[0.0; 13]).unwrap();
    let p = zero.translation.vector;
    assert!(
        (p.x - (-0.10)).abs() < 1e-12 && (p.y - 0.22).abs() < 1e-12 && (p.z - 0.50).abs() < 1e-12
    );
}

#[test]
fn right_arm_4_matches_hand_derived_transforms() {
    let chain = loki().body_part("right_arm_4").unwrap();
    for q in [[0.0; 4], [-0.5, -1.0, 0.3, -1.2], [0.9, 0.2, -1.7, -2.0]] {
        assert_close(
            "right_arm_4",
            &chain.fk(&q).unwrap().to_homogeneous(),
            &right_arm_4(&q),
        );
    }
}

#[test]
fn neck_matches_hand_derived_transforms() {
    let chain = loki().body_part("neck").unwrap();
    for q in [[0.0; 4], [0.4, -0.3, 0.2, 0.5], [-1.1, 0.55, -0.35, -0.7]] {
        assert_close("neck", &chain.fk(&q).unwrap().to_homogeneous(), &neck(&q));
    }
    // At zero the camera looks forward (+x of the torso) from 1 m... its optical z is torso +x.
    let t = chain.fk(&[0.0; 4]).unwrap();
    let z = t.rotation * nalgebra::Vector3::z();
    assert!((z - nalgebra::Vector3::x()).norm() < 1e-12);
}
