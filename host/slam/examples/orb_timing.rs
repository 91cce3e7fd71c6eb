//! Times ORB extraction on a snapshot's rgb.png: `ferrobot snapshot locobot --scene apartment
//! --out DIR`, then `cargo run --release -p ferrobot-slam --example orb_timing -- DIR`.
use ferrobot_perception::io;
use ferrobot_slam::orb::{GreyImage, OrbExtractor, OrbSettings};
fn main() {
    let dir = std::env::args().nth(1).expect("a snapshot directory");
    let rgb = io::read_rgb_png(format!("{dir}/rgb.png")).expect("rgb.png");
    let g = GreyImage::from_rgb(rgb.width as usize, rgb.height as usize, &rgb.data).expect("rgb");
    let orb = OrbExtractor::new(OrbSettings::default());
    let t0 = std::time::Instant::now();
    let n = 50;
    let mut k = 0;
    for _ in 0..n {
        k += orb.extract(&g).keypoints.len();
    }
    println!(
        "{} features, {:?} per image",
        k / n,
        t0.elapsed() / n as u32
    );
}
