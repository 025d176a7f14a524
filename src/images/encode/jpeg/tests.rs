use super::*;

/// What `jpeg-encoder` writes for the same image: one encode of the
/// whole, with the restart interval glint's file has.
fn reference(rgb: &[u8], w: u16, h: u16, quality: u8) -> Vec<u8> {
    let mut out = Vec::new();
    let mut e = jpeg_encoder::Encoder::new(&mut out, quality);
    e.set_sampling_factor(jpeg_encoder::SamplingFactor::F_1_1);
    if usize::from(h).div_ceil(8) >= 2 * STRIP_MCU_ROWS {
        e.set_restart_interval(w.div_ceil(8));
    }
    e.encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)
        .expect("encodes");
    out
}

fn pattern(w: u32, h: u32) -> Vec<u8> {
    (0..w * h * 3)
        .map(|i| {
            let (p, c) = (i / 3, i % 3);
            let (x, y) = (p % w, p / w);
            ((x * (3 + c) + y * (5 + 2 * c) + (x * y) % 13) % 256) as u8
        })
        .collect()
}

/// Every byte from xorshift: the DCT's and quantiser's extremes.
fn noise(w: u32, h: u32, seed: u64) -> Vec<u8> {
    let mut s = seed | 1;
    (0..w * h * 3)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 24) as u8
        })
        .collect()
}

/// Hard edges between black and white: the largest coefficients.
fn checks(w: u32, h: u32) -> Vec<u8> {
    (0..w * h * 3)
        .map(|i| {
            let p = i / 3;
            if ((p % w) / 3 + (p / w) / 5).is_multiple_of(2) {
                0
            } else {
                255
            }
        })
        .collect()
}

fn kernels() -> Vec<(&'static str, Kernel)> {
    let portable = ("portable", Kernel::portable());
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        return vec![portable, ("avx2", Kernel::best())];
    }
    eprintln!("no AVX2 on this CPU: only the portable JPEG kernel is tested");
    vec![portable]
}

/// Pixels that vary along one axis only: every row the same (`rows`) or
/// every column (`!rows`). On these `jpeg-encoder`'s AVX2 DCT, whose
/// second pass leaves out the rounding of odd columns' outputs 0 and 4
/// (its rounding constant is set as 32-bit lanes and added as 16-bit
/// ones), gives its portable DCT's answer: the sums it fails to round are
/// multiples of four. So its files are an oracle for glint's here, on any
/// CPU.
fn one_axis(w: u32, h: u32, rows: bool, seed: u64) -> Vec<u8> {
    let line = noise(if rows { w } else { h }, 1, seed);
    (0..w * h)
        .flat_map(|p| {
            let i = if rows { p % w } else { p / w } as usize * 3;
            [line[i], line[i + 1], line[i + 2]]
        })
        .collect()
}

/// glint's file is `jpeg-encoder`'s, byte for byte, where the latter's
/// two DCTs agree (`one_axis`): sizes on and off the 8-pixel grid, one
/// strip and many (past the RST cycle of 8), qualities from 1 to 100,
/// noisy, smooth and hard-edged content along each axis, each kernel.
#[test]
fn same_bytes_as_jpeg_encoder() {
    for (name, kernel) in kernels() {
        // 248 and 249 rows: the last height with one strip and no restart
        // markers, and the first with two strips and markers.
        for (w, h) in [
            (1, 1),
            (7, 5),
            (8, 8),
            (17, 9),
            (9, 248),
            (9, 249),
            (640, 480),
            (100, 1037),
            (17, 2000),
        ] {
            let seed = u64::from(w * 31 + h);
            let smooth = |rows: bool| -> Vec<u8> {
                (0..w * h)
                    .flat_map(|p| {
                        let t = if rows { p % w } else { p / w };
                        [(t * 3) as u8, (t * 5 / 2) as u8, 255 - (t % 256) as u8]
                    })
                    .collect()
            };
            for (content, rgb) in [
                ("noise along x", one_axis(w, h, true, seed)),
                ("noise along y", one_axis(w, h, false, seed)),
                ("ramps along x", smooth(true)),
                ("ramps along y", smooth(false)),
            ] {
                for quality in [1, 50, 95, 100] {
                    let ours = encode_with(&rgb, w, h, quality, kernel).expect("encodes");
                    let theirs = reference(&rgb, w as u16, h as u16, quality);
                    assert!(
                        ours == theirs,
                        "{name} kernel, {w}x{h} {content} at quality {quality}: \
                         {} bytes against jpeg-encoder's {}",
                        ours.len(),
                        theirs.len()
                    );
                }
            }
        }
    }
}

/// Where pixels vary both ways the AVX2 kernel still writes the portable
/// kernel's bytes.
#[test]
fn kernels_agree() {
    let kernels = kernels();
    let [(_, portable), rest @ ..] = &kernels[..] else {
        unreachable!("the portable kernel is always there")
    };
    for (w, h) in [(7, 5), (640, 480), (100, 1037)] {
        for rgb in [pattern(w, h), noise(w, h, 7), checks(w, h)] {
            for quality in [1, 95, 100] {
                let want = encode_with(&rgb, w, h, quality, *portable).expect("encodes");
                for (name, kernel) in rest {
                    let got = encode_with(&rgb, w, h, quality, *kernel).expect("encodes");
                    assert!(got == want, "{name} kernel, {w}x{h} at quality {quality}");
                }
            }
        }
    }
}

/// The integer DCT is the true one scaled by eight, to within its
/// rounding, with rows and columns the right way round.
#[test]
fn dct_is_the_true_dct() {
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..2000 {
        let mut block = [0i32; 64];
        for v in &mut block {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            *v = i32::from((s >> 24) as u8) - 128;
        }
        let input = block;
        block::fdct(&mut block);
        let c = |k: usize| {
            if k == 0 {
                std::f64::consts::FRAC_1_SQRT_2
            } else {
                1.0
            }
        };
        for (i, &got) in block.iter().enumerate() {
            let (v, u) = (i / 8, i % 8);
            let mut sum = 0.0;
            for (j, &x) in input.iter().enumerate() {
                let (y, xx) = (j / 8, j % 8);
                let cos = |a: usize, b: usize| {
                    ((2 * a + 1) as f64 * b as f64 * std::f64::consts::PI / 16.0).cos()
                };
                sum += f64::from(x) * cos(xx, u) * cos(y, v);
            }
            let want = 2.0 * c(u) * c(v) * sum;
            assert!(
                (f64::from(got) - want).abs() <= 2.0,
                "coefficient ({u}, {v}): {got} against {want:.2}"
            );
        }
    }
}

#[test]
fn zigzag_visits_every_coefficient_once() {
    let mut seen = [false; 64];
    for &i in &ZIGZAG {
        assert!(!seen[usize::from(i)]);
        seen[usize::from(i)] = true;
    }
    assert_eq!(ZIGZAG[..10], [0, 1, 8, 16, 9, 2, 3, 10, 17, 24]);
    assert_eq!(ZIGZAG[60..], [47, 55, 62, 63]);
}

#[test]
fn refuses_sizes_jpeg_cannot_hold() {
    assert!(encode(&[], 0, 4, 90).is_err());
    assert!(encode(&[0; 9], 70_000, 1, 90).is_err());
    assert!(encode(&[0; 5], 1, 2, 90).is_err());
}

/// The SSE2 non-zero mask is the plain loop's.
#[test]
fn nonzero_masks_agree() {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    for _ in 0..10_000 {
        let block: [i16; 64] = std::array::from_fn(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            // Mostly zeros, as quantised blocks are; the extremes too.
            match s % 8 {
                0 => i16::MIN,
                1 => i16::MAX,
                2 | 3 => (s >> 40) as i16,
                _ => 0,
            }
        });
        assert_eq!(
            scan::natural_bits(&block),
            scan::natural_bits_portable(&block)
        );
    }
}

/// However many strips the threads make, the file is the same.
#[test]
fn the_file_does_not_depend_on_the_threads() {
    let (w, h) = (333, 1100);
    let rgb = noise(w, h, 5);
    let in_pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
            .install(|| encode(&rgb, w, h, 90).expect("encodes"))
    };
    let one = in_pool(1);
    for threads in [2, 3, 7] {
        assert!(in_pool(threads) == one, "{threads} threads");
    }
}
