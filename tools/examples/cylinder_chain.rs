//! Writes a synthetic example set of chosen size ([`rrskin_tools::cylinder_chain`]), to time
//! training at scale:
//!
//!     cargo run --release -p rrskin-tools --example cylinder_chain -- OUT [RINGS SEGMENTS BONES POSES]
//!     cargo run --release -p rrskin-tools -- train OUT -o chain.rrs
//!
//! The defaults (100 rings x 80 segments, 6 bones, 30 poses, the last 6 held out) give 8000
//! vertices and 15,840 triangles.

use rrskin_tools::cylinder_chain::Chain;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args
        .first()
        .ok_or("usage: cylinder_chain OUT [RINGS SEGMENTS BONES POSES]")?;
    let arg = |i: usize, default: usize| -> Result<usize, Box<dyn std::error::Error>> {
        Ok(args
            .get(i)
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(default))
    };
    let chain = Chain {
        rings: arg(1, 100)?,
        segments: arg(2, 80)?,
        bones: arg(3, 6)?,
        poses: arg(4, 30)?,
    };
    let set = chain
        .build()
        .ok_or("need RINGS >= 2, SEGMENTS >= 3, BONES >= 1, POSES >= 2")?;
    set.save(out)?;
    eprintln!(
        "wrote {out}: {} vertices, {} triangles, {} bones, {} poses",
        set.vertex_count(),
        set.faces.len(),
        chain.bones,
        chain.poses
    );
    Ok(())
}
