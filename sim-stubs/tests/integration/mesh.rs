//! Mesh files and primitives (`ferrobot_sim::mesh`): closed primitives enclose their volume,
//! and hostile mesh files are errors.

use ferrobot_sim::mesh::{parse, TriMesh};

#[test]
fn closed_primitives_enclose_their_volume() {
    let b = TriMesh::cuboid([0.1, 0.2, 0.3]);
    assert!((b.volume() - 0.006).abs() < 1e-12, "{}", b.volume());
    let c = TriMesh::cylinder(0.05, 0.2, 64);
    let exact = std::f64::consts::PI * 0.05 * 0.05 * 0.2;
    assert!((c.volume() - exact).abs() / exact < 0.01, "{}", c.volume());
    let s = TriMesh::capsule(0.05, 0.0, 48);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.05f64.powi(3);
    assert!((s.volume() - exact).abs() / exact < 0.02, "{}", s.volume());
}

#[test]
fn hostile_mesh_files_are_errors() {
    assert!(parse("x.obj", b"v 0 0 0\nf 1 2 3\n").is_err());
    assert!(parse("x.obj", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").is_err());
    assert!(parse("x.stl", &[0u8; 10]).is_err());
    assert!(parse("x.ply", b"").is_err());
    assert!(parse("x.obj", b"").is_err());
    assert!(parse("x.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").is_ok());
}
