//! Learns how MediaPipe's 468 face-mesh vertices give each of the 68 iBUG points and rewrites
//! `src/find/mesh_table_data.rs` (see `src/find/mesh_table.rs`), from the GRID frames
//! committed in `data/grid`:
//! 1. for each point, its main vertex: the one whose offset from dlib's point, in the face
//!    frame of dlib's points, has the least variance plus half its squared mean;
//! 2. the [`BLEND`] - 1 other vertices nearest dlib's mean point (in the face frame of the
//!    main vertices' 68 points), and weights for all [`BLEND`] that sum to 1, by ridge least
//!    squares of dlib's point on the vertices' offsets from the main one (plus a free offset,
//!    which the calibration then learns: `finder_data -- calibration`).
//!
//! `cargo run --release --example mesh_table`, then `cargo run --release --example
//! finder_data -- calibration`.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads and writes files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::find::{face_frame, MESH_POINTS};
    use facemimic::io::{annotated_images, read_image, read_landmarks};
    use facemimic::FaceFinder;
    use nalgebra::{DMatrix, DVector};
    use std::path::Path;

    /// The weight of the squared mean offset beside the offset's variance when the main vertex
    /// is chosen: the calibration removes the mean, but a vertex far from dlib's point moves
    /// differently when the head turns.
    const MEAN_WEIGHT: f64 = 0.5;
    /// Vertices blended per point (`mesh_table::BLEND`).
    const BLEND: usize = 3;
    /// The ridge on the blend weights, per frame (the weights' penalty is `RIDGE * frames *
    /// |w|^2` against a sum of squares over the frames in the face frame's units).
    const RIDGE: f64 = 0.001;

    /// A committed frame: the mesh (x, y, z per vertex) and dlib's 68 points.
    type Frame = (Vec<f32>, Vec<f32>);
    /// A frame in a face frame: the mesh's vertices and dlib's points, `(x, y)` each.
    type Local = (Vec<[f64; 2]>, Vec<[f64; 2]>);

    fn frames() -> Vec<Frame> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid");
        let mut finder = FaceFinder::new().unwrap();
        let mut out = Vec::new();
        for p in annotated_images(&dir).unwrap() {
            let img = read_image(&p).unwrap();
            let truth = read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
            if let Some(mesh) = finder.dense_meshes(&img.view().unwrap()).into_iter().next() {
                if face_frame(&truth).is_some() {
                    out.push((mesh, truth));
                }
            }
        }
        out
    }

    /// `(x, y)` of `p` in the face frame `(centre, radius, cos, sin)`.
    fn to_frame(f: &([f32; 2], f32, f32, f32), p: [f32; 2]) -> [f64; 2] {
        let (c0, r, c, s) = f;
        let (dx, dy) = (p[0] - c0[0], p[1] - c0[1]);
        [
            ((c * dx + s * dy) / r) as f64,
            ((-s * dx + c * dy) / r) as f64,
        ]
    }

    /// Step 1: each point's main vertex.
    fn main_vertices(frames: &[Frame]) -> Vec<usize> {
        let n = MESH_POINTS;
        let mut sum = vec![[0.0f64; 2]; 68 * n];
        let mut sq = vec![0.0f64; 68 * n];
        for (mesh, truth) in frames {
            let (_, r, c, s) = face_frame(truth).unwrap();
            for j in 0..68 {
                let (tx, ty) = (truth[2 * j], truth[2 * j + 1]);
                for v in 0..n {
                    let (dx, dy) = (mesh[3 * v] - tx, mesh[3 * v + 1] - ty);
                    let o = [
                        ((c * dx + s * dy) / r) as f64,
                        ((-s * dx + c * dy) / r) as f64,
                    ];
                    let k = j * n + v;
                    sum[k][0] += o[0];
                    sum[k][1] += o[1];
                    sq[k] += o[0] * o[0] + o[1] * o[1];
                }
            }
        }
        let f = frames.len() as f64;
        (0..68)
            .map(|j| {
                (0..n)
                    .min_by(|&a, &b| {
                        // Spread plus a share of the mean offset: stable and near.
                        let cost = |v: usize| {
                            let m = sum[j * n + v];
                            let mean2 = (m[0] * m[0] + m[1] * m[1]) / (f * f);
                            sq[j * n + v] / f - mean2 + MEAN_WEIGHT * mean2
                        };
                        cost(a).total_cmp(&cost(b))
                    })
                    .expect("a vertex near every point")
            })
            .collect()
    }

    /// Step 2: each point's vertices (main first) and weights.
    fn blend(frames: &[Frame], main: &[usize]) -> Vec<([usize; BLEND], [f64; BLEND])> {
        // Every frame in the face frame of its main vertices' 68 points.
        let local: Vec<Local> = frames
            .iter()
            .map(|(mesh, truth)| {
                let pts: Vec<f32> = main
                    .iter()
                    .flat_map(|&v| [mesh[3 * v], mesh[3 * v + 1]])
                    .collect();
                let f = face_frame(&pts).expect("a face");
                let m = (0..MESH_POINTS)
                    .map(|v| to_frame(&f, [mesh[3 * v], mesh[3 * v + 1]]))
                    .collect();
                let t = truth
                    .chunks_exact(2)
                    .map(|p| to_frame(&f, [p[0], p[1]]))
                    .collect();
                (m, t)
            })
            .collect();
        let nf = local.len() as f64;
        let mean = |get: &dyn Fn(&Local) -> [f64; 2]| {
            let s = local
                .iter()
                .map(get)
                .fold([0.0, 0.0], |a, b| [a[0] + b[0], a[1] + b[1]]);
            [s[0] / nf, s[1] / nf]
        };
        (0..68)
            .map(|j| {
                let target = mean(&|(_, t)| t[j]);
                let mut near: Vec<(f64, usize)> = (0..MESH_POINTS)
                    .filter(|&v| v != main[j])
                    .map(|v| {
                        let m = mean(&|(m, _)| m[v]);
                        ((m[0] - target[0]).hypot(m[1] - target[1]), v)
                    })
                    .collect();
                near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let mut verts = [main[j]; BLEND];
                for (k, &(_, v)) in near.iter().take(BLEND - 1).enumerate() {
                    verts[k + 1] = v;
                }
                // Rows: x then y of every frame; unknowns: the other vertices' weights, then
                // the x and y offsets (not penalised).
                let (k, rows) = (BLEND - 1, 2 * local.len());
                let mut a = DMatrix::<f64>::zeros(rows, k + 2);
                let mut b = DVector::<f64>::zeros(rows);
                for (i, (m, t)) in local.iter().enumerate() {
                    let m0 = m[main[j]];
                    for d in 0..2 {
                        let row = 2 * i + d;
                        for (c, &v) in verts[1..].iter().enumerate() {
                            a[(row, c)] = m[v][d] - m0[d];
                        }
                        a[(row, k + d)] = 1.0;
                        b[row] = t[j][d] - m0[d];
                    }
                }
                let mut normal = a.transpose() * &a;
                for c in 0..k {
                    normal[(c, c)] += RIDGE * nf;
                }
                let w = normal
                    .cholesky()
                    .expect("a positive definite system")
                    .solve(&(a.transpose() * b));
                let mut weights = [0.0; BLEND];
                for c in 0..k {
                    weights[c + 1] = w[c];
                }
                weights[0] = 1.0 - weights[1..].iter().sum::<f64>();
                (verts, weights)
            })
            .collect()
    }

    /// Step 3: each point's depth (the blend of its vertices' z, away from the camera), in
    /// units of the face frame's radius, less the 68 points' mean, averaged over the frames.
    fn depths(frames: &[Frame], table: &[([usize; BLEND], [f64; BLEND])]) -> [f64; 68] {
        let mut sum = [0.0; 68];
        for (mesh, _) in frames {
            let blend = |d: usize| -> Vec<f32> {
                table
                    .iter()
                    .map(|(v, w)| {
                        v.iter()
                            .zip(w)
                            .map(|(&v, &w)| w as f32 * mesh[3 * v + d])
                            .sum()
                    })
                    .collect()
            };
            let (x, y, z) = (blend(0), blend(1), blend(2));
            let pts: Vec<f32> = x.iter().zip(&y).flat_map(|(&x, &y)| [x, y]).collect();
            let (_, r, _, _) = face_frame(&pts).expect("a face");
            let mean = z.iter().sum::<f32>() / 68.0;
            for (s, z) in sum.iter_mut().zip(&z) {
                *s += ((z - mean) / r) as f64;
            }
        }
        sum.map(|s| s / frames.len() as f64)
    }

    pub(crate) fn main() {
        let frames = frames();
        let main = main_vertices(&frames);
        let table = blend(&frames, &main);
        let depth = depths(&frames, &table);
        let mut text = format!(
            "// Generated by `cargo run --release --example mesh_table`\n\
             // from the {} committed GRID frames of data/grid: see mesh_table.rs.\n\n\
             /// For each of the 68 iBUG points, its face-mesh vertices (the main one first).\n\
             pub(crate) const MESH_TO_IBUG: [[u16; BLEND]; 68] = [\n",
            frames.len()
        );
        for (verts, _) in &table {
            let items: Vec<String> = verts.iter().map(|v| v.to_string()).collect();
            text.push_str(&format!("    [{}],\n", items.join(", ")));
        }
        text.push_str(
            "];\n\n/// For each of the 68 iBUG points, the weights of its vertices (summing to 1).\n\
             pub(crate) const MESH_WEIGHTS: [[f32; BLEND]; 68] = [\n",
        );
        for (_, w) in &table {
            let items: Vec<String> = w.iter().map(|&v| format!("{:?}", v as f32)).collect();
            text.push_str(&format!("    [{}],\n", items.join(", ")));
        }
        text.push_str(
            "];\n\n/// For each of the 68 iBUG points, its mean depth (away from the camera) in the face\n\
             /// frame (units of the RMS radius; the 68 points' mean is 0).\n\
             pub(crate) const IBUG_DEPTH_DATA: [f32; 68] = [\n",
        );
        for row in depth.chunks(6) {
            let items: Vec<String> = row.iter().map(|&v| format!("{:?}", v as f32)).collect();
            text.push_str(&format!("    {},\n", items.join(", ")));
        }
        text.push_str("];\n");
        let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/find/mesh_table_data.rs");
        std::fs::write(&out, text).unwrap();
        eprintln!("{} frames -> {}", frames.len(), out.display());
    }
}
