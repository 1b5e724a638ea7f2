//! Meshes the built-in torus with the library's entry point and writes a PLY file.
//!
//! `cargo run --release --example torus [OUT.ply]`

fn main() -> isomesh::Result<()> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "torus.ply".into());
    let torus = isomesh::Mesher::preset("torus", &[])?.edge(0.05).trace()?;
    let t = torus.topology()?;
    println!(
        "{} points, Euler characteristic {}",
        torus.len(),
        t.euler_characteristic
    );
    torus.write(&out)?;
    println!("wrote {out}");
    Ok(())
}
