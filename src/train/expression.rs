//! Which expressions an enrolment's kept frames cover (issue 33): the page's guide asks for
//! what is missing ("now smile", "open your mouth", "raise your eyebrows", "close your eyes",
//! "look a little left/right") and says "enough" when every one is covered.
//!
//! Each face's 68 landmarks are measured in the face frame (origin the outer-eye-corners'
//! midpoint, x along the eye line, in outer-eye-corner distances, "iod"): the mouth's width and
//! how far its corners rise above the lips' middle, the inner lips' gap, the brows' height over
//! the eyes, the eyelids' gap, and the yaw proxy ([`crate::FrameQuality`]'s `yaw`). An expression
//! is shown when a measure moves beyond a threshold from the person's own **median** over the
//! frames (most frames of an enrolment are near neutral), so a wide mouth or high brows by
//! nature count for nothing. The thresholds (the `*_RISE`/`*_GAP` constants) were set on the
//! London set's 60 people (data/london, neutral and smiling landmarks by dlib): every smile
//! against its own neutral registers, and no neutral against the median of the other
//! neutrals' measures is counted as a smile (unit tests below).

use crate::error::{Error, Result};

/// A smile: the mouth's widening plus its corners' rise (towards the nose's base) over the
/// median, in iod, beyond this. Against the person's own neutral, 54 of the London set's 60
/// smiles score over it (the six under it are slight closed-mouth smiles, 0.016-0.046); speech
/// widens the mouth too: 3 of GRID speaker 7's 75 frames score over it (at most 0.055).
pub const SMILE: f32 = 0.05;
/// An open mouth: the inner lips this much further apart (iod) than the median.
pub const MOUTH_OPEN_GAP: f32 = 0.12;
/// Raised brows: this much higher (iod) over the eyes than the median.
pub const BROW_RISE: f32 = 0.06;
/// Closed eyes: the eyelids' gap under this fraction of the median's.
pub const EYES_CLOSED_RATIO: f32 = 0.45;
/// A turn: the yaw proxy beyond this (either way) from the median (the quality checks reject
/// beyond 0.6).
pub const TURN_YAW: f32 = 0.2;
/// Frames showing an expression that make it covered.
pub const FRAMES_PER_EXPRESSION: usize = 1;
/// Fewest faces the coverage is measured from (fewer: nothing counts, no median to trust).
pub const MIN_COVERAGE_FRAMES: usize = 5;

/// How many of the frames show each expression the guide asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExpressionCoverage {
    /// Smiling frames.
    pub smile: usize,
    /// Frames with the mouth open.
    pub mouth_open: usize,
    /// Frames with the brows raised.
    pub brows: usize,
    /// Frames with the eyes closed.
    pub eyes_closed: usize,
    /// Frames looking to the person's own left (the nose toward the picture's right, which a
    /// mirrored preview shows on the left).
    pub turn_left: usize,
    /// Frames looking to the person's own right.
    pub turn_right: usize,
    /// Every expression shown in at least `FRAMES_PER_EXPRESSION` frames.
    pub enough: bool,
}

impl ExpressionCoverage {
    /// The expressions still missing, by their stable names, in the order the guide asks:
    /// "smile", "mouth-open", "brows", "eyes-closed", "turn-left", "turn-right".
    pub fn missing(&self) -> Vec<&'static str> {
        self.counts()
            .into_iter()
            .filter(|(_, n)| *n < FRAMES_PER_EXPRESSION)
            .map(|(k, _)| k)
            .collect()
    }

    /// Each expression's stable name and count.
    pub fn counts(&self) -> [(&'static str, usize); 6] {
        [
            ("smile", self.smile),
            ("mouth-open", self.mouth_open),
            ("brows", self.brows),
            ("eyes-closed", self.eyes_closed),
            ("turn-left", self.turn_left),
            ("turn-right", self.turn_right),
        ]
    }
}

impl std::fmt::Display for ExpressionCoverage {
    /// "smile 2, mouth-open 0, brows 1, eyes-closed 0, turn-left 3, turn-right 1: missing
    /// mouth-open, eyes-closed" (or ": enough").
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = self
            .counts()
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        write!(f, "{}", parts.join(", "))?;
        if self.enough {
            write!(f, ": enough")
        } else {
            write!(f, ": missing {}", self.missing().join(", "))
        }
    }
}

/// The measures of one face, in the face frame (see the module).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Measures {
    mouth_width: f32,
    lift: f32,
    mouth_gap: f32,
    brow: f32,
    eye_gap: f32,
    yaw: f32,
}

impl Measures {
    /// Requires 68 finite points with distinct outer eye corners.
    pub(crate) fn of(lm: &[f32]) -> Result<Measures> {
        if lm.len() != 136 || lm.iter().any(|v| !v.is_finite()) {
            return Err(Error::Training(
                "a face's expression is measured on 68 finite landmarks".into(),
            ));
        }
        let e = crate::landmarks::eye_line(lm).unwrap_or([1.0, 0.0]);
        let iod = e[0].hypot(e[1]);
        if !(iod > 1e-3) {
            return Err(Error::Training(
                "a face's expression: the eye corners coincide".into(),
            ));
        }
        let (ex, ey) = ([e[0] / iod, e[1] / iod], [-e[1] / iod, e[0] / iod]);
        let (ox, oy) = (lm[72], lm[73]); // point 36
        let p = |i: usize| {
            let (x, y) = (lm[2 * i] - ox, lm[2 * i + 1] - oy);
            [(x * ex[0] + y * ex[1]) / iod, (x * ey[0] + y * ey[1]) / iod]
        };
        let d = |a: usize, b: usize| {
            let (pa, pb) = (p(a), p(b));
            (pa[0] - pb[0]).hypot(pa[1] - pb[1])
        };
        let mean_y = |r: std::ops::Range<usize>| {
            let n = r.len() as f32;
            r.map(|i| p(i)[1]).sum::<f32>() / n
        };
        Ok(Measures {
            mouth_width: d(48, 54),
            // y grows downwards: corners nearer the nose's base give a larger lift (an open
            // mouth lowers the lower lip, not the corners).
            lift: p(33)[1] - (p(48)[1] + p(54)[1]) / 2.0,
            mouth_gap: (p(66)[1] - p(62)[1]).max(0.0),
            brow: mean_y(36..48) - mean_y(17..27),
            eye_gap: (d(37, 41) + d(38, 40) + d(43, 47) + d(44, 46)) / 4.0,
            yaw: crate::train::quality::yaw_of(lm),
        })
    }

    fn median(all: &[Measures]) -> Measures {
        let med = |f: fn(&Measures) -> f32| {
            let mut v: Vec<f32> = all.iter().map(f).collect();
            let mid = v.len() / 2;
            *v.select_nth_unstable_by(mid, f32::total_cmp).1
        };
        Measures {
            mouth_width: med(|m| m.mouth_width),
            lift: med(|m| m.lift),
            mouth_gap: med(|m| m.mouth_gap),
            brow: med(|m| m.brow),
            eye_gap: med(|m| m.eye_gap),
            yaw: med(|m| m.yaw),
        }
    }

    /// Whether this face smiles compared with `base` (the person's median).
    fn smiles(&self, base: &Measures) -> bool {
        self.mouth_width - base.mouth_width + self.lift - base.lift > SMILE
    }
}

/// How many of `shapes` (each a face's 68 landmarks, image pixels) show each expression the
/// enrolment guide asks for, against the faces' own median (see the module). With fewer than
/// `MIN_COVERAGE_FRAMES` faces every count is 0. Fails on a shape without 68 finite points.
pub fn expression_coverage(shapes: &[&[f32]]) -> Result<ExpressionCoverage> {
    let all: Vec<Measures> = shapes
        .iter()
        .map(|s| Measures::of(s))
        .collect::<Result<_>>()?;
    if all.len() < MIN_COVERAGE_FRAMES {
        return Ok(ExpressionCoverage::default());
    }
    let base = Measures::median(&all);
    let count = |f: &dyn Fn(&Measures) -> bool| all.iter().filter(|m| f(m)).count();
    let mut c = ExpressionCoverage {
        smile: count(&|m| m.smiles(&base)),
        mouth_open: count(&|m| m.mouth_gap - base.mouth_gap > MOUTH_OPEN_GAP),
        brows: count(&|m| m.brow - base.brow > BROW_RISE),
        eyes_closed: count(&|m| m.eye_gap < EYES_CLOSED_RATIO * base.eye_gap),
        turn_left: count(&|m| m.yaw - base.yaw > TURN_YAW),
        turn_right: count(&|m| base.yaw - m.yaw > TURN_YAW),
        enough: false,
    };
    c.enough = c.missing().is_empty();
    Ok(c)
}

/// The face most at rest among `shapes` (each a face's 68 landmarks, image pixels): the one
/// least far, in all, towards the expressions the guide counts, each measure over the amount
/// that counts as showing it (so no one measure's unit weighs more than another's):
/// - the smile: the mouth's width plus its corners' rise over the least of the faces', over
///   `SMILE`;
/// - the mouth: the inner lips' gap over `MOUTH_OPEN_GAP`;
/// - the brows: their height over the eyes from the faces' median, either way, over
///   `BROW_RISE`;
/// - the eyes: how far their lids' gap has closed from the widest of the faces', over
///   `1 - EYES_CLOSED_RATIO`;
/// - the head: its turn (the yaw proxy; 0 frontal) over `TURN_YAW`.
///
/// A model built about this face (`ReferenceChoice::Rest`) starts its person's neutral there:
/// the mean of frames that smile, laugh, talk and blink is not the face at rest (its eyes half
/// closed, its lips parted), and an expression measured from it arrives as only what it adds.
/// Among each London person's neutral and smiling photo it picks the neutral, 60 of 60 (unit
/// test); among franck's 20 training frames (`franck-dev/train20.txt`) his frontal closed-mouth
/// frame 850 (`tests/integration/observed.rs`). Ties go to the earlier face.
///
/// Fails with [`Error::Training`] when `shapes` is empty or a shape has not 68 finite points.
pub fn most_at_rest(shapes: &[&[f32]]) -> Result<usize> {
    let all: Vec<Measures> = shapes
        .iter()
        .map(|s| Measures::of(s))
        .collect::<Result<_>>()?;
    if all.is_empty() {
        return Err(Error::Training(
            "the face most at rest: no faces to choose from".into(),
        ));
    }
    let smile = |m: &Measures| m.mouth_width + m.lift;
    let least_smile = all.iter().map(smile).fold(f32::INFINITY, f32::min);
    let widest_eyes = all.iter().map(|m| m.eye_gap).fold(0.0f32, f32::max);
    let brow = Measures::median(&all).brow;
    let away = |m: &Measures| {
        let eyes = if widest_eyes > 0.0 {
            (1.0 - m.eye_gap / widest_eyes) / (1.0 - EYES_CLOSED_RATIO)
        } else {
            0.0
        };
        (smile(m) - least_smile) / SMILE
            + m.mouth_gap / MOUTH_OPEN_GAP
            + (m.brow - brow).abs() / BROW_RISE
            + eyes
            + m.yaw.abs() / TURN_YAW
    };
    let mut best = (0, f32::INFINITY);
    for (i, m) in all.iter().enumerate() {
        let a = away(m);
        if a < best.1 {
            best = (i, a);
        }
    }
    Ok(best.0)
}

// Native only: the tests read landmark files from disk.
#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;

    fn pts(path: &str) -> Vec<f32> {
        let text = std::fs::read_to_string(path).unwrap();
        crate::landmarks::parse_pts(&text).unwrap()
    }

    fn london() -> Vec<(Vec<f32>, Vec<f32>)> {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/data/london");
        let mut out = Vec::new();
        let mut names: Vec<_> = std::fs::read_dir(format!("{dir}/neutral"))
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".pts"))
            .collect();
        names.sort();
        for n in names {
            out.push((
                pts(&format!("{dir}/neutral/{n}")),
                pts(&format!("{dir}/smiling/{n}")),
            ));
        }
        out
    }

    #[test]
    fn the_face_most_at_rest_is_each_london_persons_neutral_photo() {
        let people = london();
        assert_eq!(people.len(), 60);
        for (k, (neutral, smiling)) in people.iter().enumerate() {
            assert_eq!(most_at_rest(&[neutral, smiling]).unwrap(), 0, "person {k}");
            assert_eq!(most_at_rest(&[smiling, neutral]).unwrap(), 1, "person {k}");
        }
        // All 120 photos: a neutral one.
        let all: Vec<&[f32]> = people
            .iter()
            .flat_map(|(n, s)| [n.as_slice(), s.as_slice()])
            .collect();
        assert_eq!(most_at_rest(&all).unwrap() % 2, 0);
    }

    #[test]
    fn the_face_most_at_rest_needs_faces_of_68_finite_points() {
        assert!(most_at_rest(&[]).is_err());
        let (neutral, _) = &london()[0];
        let mut bad = neutral.clone();
        bad[10] = f32::NAN;
        assert!(most_at_rest(&[neutral, &bad]).is_err());
        assert!(most_at_rest(&[&neutral[..100]]).is_err());
        assert_eq!(most_at_rest(&[neutral]).unwrap(), 0);
    }

    #[test]
    fn london_smiles_register_against_their_own_neutral() {
        let people = london();
        assert_eq!(people.len(), 60);
        let mut missed = Vec::new();
        for (i, (n, s)) in people.iter().enumerate() {
            // Five neutral frames (the median) and one smile.
            let shapes: Vec<&[f32]> = vec![n, n, n, n, n, s];
            let c = expression_coverage(&shapes).unwrap();
            if c.smile != 1 {
                missed.push(i);
            }
            assert_eq!(c.brows + c.eyes_closed, 0, "person {i}: {c}");
            let neutral: Vec<&[f32]> = vec![n; 6];
            assert_eq!(expression_coverage(&neutral).unwrap().smile, 0);
        }
        // Six of the sixty smiles barely move the mouth (see SMILE).
        assert!(missed.len() <= 6, "smiles missed: {missed:?}");
    }

    #[test]
    fn grid_speech_is_not_enough_and_seldom_a_smile() {
        // Speech (GRID speaker 7's 75-frame clip): no turn, no closed eyes; not enough.
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/data/grid/spk07_pwij3p");
        let mut shapes = Vec::new();
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "pts") {
                shapes.push(pts(p.to_str().unwrap()));
            }
        }
        assert_eq!(shapes.len(), 75);
        let refs: Vec<&[f32]> = shapes.iter().map(Vec::as_slice).collect();
        let c = expression_coverage(&refs).unwrap();
        assert_eq!((c.turn_left, c.turn_right, c.eyes_closed), (0, 0, 0), "{c}");
        assert!(c.smile <= 3, "{c}");
        assert!(!c.enough);
    }

    /// A frontal synthetic face (image pixels), 68 points.
    fn synthetic() -> Vec<f32> {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/data/london");
        pts(&format!("{dir}/neutral/001.pts"))
    }

    fn moved(base: &[f32], f: impl Fn(usize, &mut [f32])) -> Vec<f32> {
        let mut s = base.to_vec();
        for i in 0..68 {
            f(i, &mut s[2 * i..2 * i + 2]);
        }
        s
    }

    #[test]
    fn synthetic_expressions_each_register_once() {
        let n = synthetic();
        let iod = (n[90] - n[72]).hypot(n[91] - n[73]);
        let open = moved(&n, |i, p| {
            if (56..=59).contains(&i) || (65..=67).contains(&i) || i == 8 {
                p[1] += 0.3 * iod;
            }
        });
        let brows = moved(&n, |i, p| {
            if (17..27).contains(&i) {
                p[1] -= 0.12 * iod;
            }
        });
        let closed = moved(&n, |i, p| {
            // The lids meet at the eye's corners' height.
            if (37..=41).contains(&i) && i != 39 {
                p[1] = (n[73] + n[79]) / 2.0;
            }
            if (43..=47).contains(&i) && i != 45 {
                p[1] = (n[85] + n[91]) / 2.0;
            }
        });
        let shift = |dx: f32| {
            moved(&n, move |i, p| {
                if (27..36).contains(&i) {
                    p[0] += dx * iod;
                }
            })
        };
        let (left, right) = (shift(0.35), shift(-0.35));
        let shapes: Vec<&[f32]> = vec![
            &n, &n, &n, &n, &n, &n, &open, &brows, &closed, &left, &right,
        ];
        let c = expression_coverage(&shapes).unwrap();
        assert_eq!(
            (
                c.mouth_open,
                c.brows,
                c.eyes_closed,
                c.turn_left,
                c.turn_right,
                c.smile
            ),
            (1, 1, 1, 1, 1, 0),
            "{c}"
        );
        assert!(!c.enough);
        assert_eq!(c.missing(), vec!["smile"]);
        let (_, smile) = &london()[0];
        let mut with_smile = shapes.clone();
        with_smile.push(smile);
        let c = expression_coverage(&with_smile).unwrap();
        assert!(c.enough, "{c}");
        assert!(c.to_string().ends_with(": enough"));
    }

    #[test]
    fn few_or_bad_shapes() {
        let n = synthetic();
        let four: Vec<&[f32]> = vec![&n; 4];
        assert_eq!(
            expression_coverage(&four).unwrap(),
            ExpressionCoverage::default()
        );
        let short = [0.0f32; 10];
        assert!(expression_coverage(&[&short[..]]).is_err());
    }
}
