use super::*;

fn nickel() -> Arc<dyn Brdf> {
    acdf_materials::builtin("nickel").expect("built-in nickel")
}

fn small(brdf: Arc<dyn Brdf>) -> OutgoingSampler {
    let builder = OutgoingBuilder::by_name("chi2", None, 32).unwrap();
    OutgoingSampler::new(brdf, "8x1x64x16".parse().unwrap(), builder).unwrap()
}

fn direction(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// The density is continuous in wo across a breakpoint: just below, at
/// and just above it, the densities of fixed wi agree to within the
/// change of the blend weight (against a jump between two different
/// slices, which a breakpoint picking one slice on each side would give).
#[test]
fn pdf_is_continuous_across_a_breakpoint() {
    let s = small(nickel());
    let angles = s.breakpoint_angles();
    assert!(angles.len() >= 3, "{angles:?}");
    let theta = angles[angles.len() / 2];
    let wis: Vec<Vec3> = (0..40)
        .map(|k| direction(0.02 + 1.5 * k as f32 / 40.0, 0.3 + 0.15 * k as f32))
        .collect();
    let mut compared = 0;
    for wi in wis {
        let at = s.pdf(direction(theta, 0.0), wi);
        let below = s.pdf(direction(theta - 1e-4, 0.0), wi);
        let above = s.pdf(direction(theta + 1e-4, 0.0), wi);
        if at > 0.0 {
            compared += 1;
            for p in [below, above] {
                assert!((p - at).abs() <= 0.02 * at, "{p} against {at} at {wi}");
            }
        }
    }
    assert!(compared > 20);
    // The neighbouring slices differ: the continuity is the blend's.
    let (a, b) = (
        s.slices().slice_cdf(angles.len() / 2 - 1),
        s.slices().slice_cdf(angles.len() / 2),
    );
    assert_ne!(a, b);
}

/// A mutant that takes the slice of the nearest breakpoint instead of
/// the blend jumps at the midpoint between breakpoints, which the
/// continuity test's comparison detects.
#[test]
fn nearest_slice_mutant_jumps() {
    let s = small(nickel());
    let angles = s.breakpoint_angles();
    let u = &s.breakpoints;
    let k = angles.len() / 2;
    let mid = 0.5 * (u[k] + u[k + 1]);
    let n = (s.n_phi_h as f32, s.n_theta_h as f32);
    let mut jumps = 0;
    for i in 0..64 {
        let (x, y) = ((i % 8) as f32 / 8.0 + 0.01, (i / 8) as f32 / 8.0 + 0.01);
        let (lo, hi) = (s.slices.pdf(k, x, y, n), s.slices.pdf(k + 1, x, y, n));
        if (lo - hi).abs() > 0.02 * lo.max(hi) {
            jumps += 1;
        }
    }
    assert!(mid > u[k] && jumps > 0);
}

/// Saved and loaded, the sampler gives the same densities and storage; a
/// flipped byte is an error, not a misread.
#[test]
fn file_round_trip() {
    let s = small(nickel()).with_cosine_mix(0.1).unwrap();
    let bytes = s.to_bytes();
    let t = OutgoingSampler::from_bytes(&bytes).unwrap();
    assert_eq!(t.storage_bytes(), s.storage_bytes());
    assert_eq!(t.brdf().fingerprint(), s.brdf().fingerprint());
    let wo = direction(0.7, 0.4);
    for k in 0..100 {
        let u = Vec2::new((k as f32 + 0.5) / 100.0, (k as f32 * 0.618).fract());
        assert_eq!(s.sample(wo, u), t.sample(wo, u));
    }
    let mut bad = bytes.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x10;
    assert!(OutgoingSampler::from_bytes(&bad).is_err());
    assert!(OutgoingSampler::from_bytes(&bytes[..bytes.len() - 3]).is_err());
}

/// Anisotropic materials are refused with a typed error.
#[test]
fn anisotropic_materials_are_refused() {
    struct Aniso(Arc<dyn Brdf>);
    impl Brdf for Aniso {
        fn name(&self) -> &str {
            "aniso"
        }
        fn eval(&self, wo: Vec3, wi: Vec3) -> acdf_core::Rgb {
            self.0.eval(wo, wi)
        }
        fn is_isotropic(&self) -> bool {
            false
        }
    }
    let builder = OutgoingBuilder::by_name("chi2", None, 8).unwrap();
    let r = OutgoingSampler::new(Arc::new(Aniso(nickel())), Resolution::ISOTROPIC, builder);
    assert!(matches!(r, Err(Error::InvalidParameter { .. })));
}

/// A storage cap raises the tolerance and the budget until the sampler
/// fits: the capped sampler stores at most the cap and records the larger
/// tolerance; without a cap the same builder stores more.
#[test]
fn storage_cap_is_kept() {
    let mut builder = OutgoingBuilder::by_name("chi2", Some(1e-3), 32).unwrap();
    assert_eq!(builder.max_bytes, None);
    let res: Resolution = "8x1x64x16".parse().unwrap();
    let free = OutgoingSampler::new(nickel(), res, builder.clone()).unwrap();
    let cap = free.storage_bytes() / 2;
    builder.max_bytes = Some(cap);
    let capped = OutgoingSampler::new(nickel(), res, builder).unwrap();
    assert!(
        capped.storage_bytes() <= cap,
        "{} > {cap}",
        capped.storage_bytes()
    );
    assert!(capped.builder().tolerance > 1e-3);
    // The default tolerance comes with the default cap.
    let default = OutgoingBuilder::by_name("chi2", None, 32).unwrap();
    assert_eq!(default.max_bytes, Some(DEFAULT_MAX_BYTES));
}

/// `sample_batch` and `pdf_batch`, which find the blend and rotation of wo
/// once and run the geometry of a chunk in lanes, give the bits of `sample`
/// and `pdf` one call at a time: at a breakpoint, between two, on the
/// normal, next to the horizon, and for an invalid wo; over several chunks
/// and a partial one, u at 0, next to 1 and outside [0, 1), and wi without
/// a density (below the horizon, opposite wo, not finite, zero). The
/// public calls take the AVX2 build where the CPU has it; each is also
/// held to the portable build of the same code (`*_one`).
#[test]
fn batch_forms_equal_single_calls() {
    let bits =
        |d: &Option<BxdfSample>| d.map(|d| (d.wi.to_array().map(f32::to_bits), d.pdf.to_bits()));
    let s = small(nickel()).with_cosine_mix(0.05).unwrap();
    let angles = s.breakpoint_angles();
    let k = angles.len() / 2;
    let mut u: Vec<Vec2> = (0..300)
        .map(|i| {
            Vec2::new(
                (i as f32 * 0.618_034).fract(),
                (i as f32 * 0.414_214).fract(),
            )
        })
        .collect();
    let below_one = acdf_core::ONE_MINUS_EPSILON;
    u.extend([
        Vec2::ZERO,
        Vec2::new(below_one, below_one),
        Vec2::new(0.02, below_one),
        Vec2::new(1.0, 0.5),
        Vec2::new(-0.5, 2.0),
        Vec2::new(f32::NAN, 0.5),
    ]);
    let thetas = [0.0, angles[k], 0.5 * (angles[k] + angles[k + 1]), 1.56];
    let mut wos: Vec<Vec3> = thetas.iter().map(|&t| direction(t, 0.7)).collect();
    wos.push(Vec3::new(0.0, 0.0, -1.0));
    for wo in wos {
        let mut drawn = vec![None; u.len()];
        s.sample_batch(wo, &u, &mut drawn);
        let mut portable = vec![None; u.len()];
        s.sample_batch_one(wo, &u, &mut portable, None);
        let mut wis = Vec::new();
        for ((&u, d), p) in u.iter().zip(&drawn).zip(&portable) {
            let one = s.sample(wo, u);
            assert_eq!(bits(&one), bits(d), "{wo} {u}");
            assert_eq!(bits(&s.sample_one(wo, u, None)), bits(d), "{wo} {u}");
            assert_eq!(bits(p), bits(d), "{wo} {u}");
            wis.push(d.map_or(direction(0.3, 2.0), |d| d.wi));
        }
        wis.extend([
            Vec3::new(0.0, 0.0, -1.0),
            -wo,
            Vec3::new(f32::NAN, 0.0, 1.0),
            Vec3::ZERO,
        ]);
        let mut densities = vec![0.0; wis.len()];
        s.pdf_batch(wo, &wis, &mut densities);
        let mut portable = vec![0.0; wis.len()];
        s.pdf_batch_one(wo, &wis, &mut portable, None);
        for ((&wi, &p), &q) in wis.iter().zip(&densities).zip(&portable) {
            assert_eq!(s.pdf(wo, wi).to_bits(), p.to_bits(), "{wo} {wi}");
            assert_eq!(s.pdf_one(wo, wi, None).to_bits(), p.to_bits(), "{wo} {wi}");
            assert_eq!(q.to_bits(), p.to_bits(), "{wo} {wi}");
        }
    }
}

/// `sample_each` and `pdf_each`, a wo per pair in chunks, give the bits of
/// `sample` and `pdf` one call at a time, in their AVX2 and portable
/// builds: wo across the hemisphere and at breakpoints, with invalid ones
/// (below the horizon, not finite) among them, over several chunks and a
/// partial one.
#[test]
fn each_forms_equal_single_calls() {
    let bits =
        |d: &Option<BxdfSample>| d.map(|d| (d.wi.to_array().map(f32::to_bits), d.pdf.to_bits()));
    let s = small(nickel()).with_cosine_mix(0.05).unwrap();
    let angles = s.breakpoint_angles();
    let n = 300;
    let wo: Vec<Vec3> = (0..n)
        .map(|i| match i % 23 {
            0 => Vec3::new(0.0, 0.0, -1.0),
            1 => Vec3::new(f32::NAN, 0.0, 1.0),
            2 => direction(angles[i % angles.len()], 1.3),
            _ => direction(
                1.56 * (i as f32 * 0.377_2).fract(),
                std::f32::consts::TAU * (i as f32 * 0.711_3).fract(),
            ),
        })
        .collect();
    let u: Vec<Vec2> = (0..n)
        .map(|i| {
            Vec2::new(
                (i as f32 * 0.618_034).fract(),
                (i as f32 * 0.414_214).fract(),
            )
        })
        .collect();
    let mut drawn = vec![None; n];
    s.sample_each(&wo, &u, &mut drawn);
    let mut portable = vec![None; n];
    s.sample_each_one(&wo, &u, &mut portable, None);
    let mut wis = Vec::new();
    for k in 0..n {
        assert_eq!(
            bits(&s.sample(wo[k], u[k])),
            bits(&drawn[k]),
            "{} {}",
            wo[k],
            u[k]
        );
        assert_eq!(bits(&portable[k]), bits(&drawn[k]), "{} {}", wo[k], u[k]);
        wis.push(drawn[k].map_or(direction(0.3, 2.0), |d| d.wi));
    }
    // Some wi without a density among the others.
    wis[5] = -wo[5];
    wis[6] = Vec3::new(0.0, 0.0, -1.0);
    let mut densities = vec![0.0; n];
    s.pdf_each(&wo, &wis, &mut densities);
    let mut portable = vec![0.0; n];
    s.pdf_each_one(&wo, &wis, &mut portable, None);
    for k in 0..n {
        assert_eq!(
            s.pdf(wo[k], wis[k]).to_bits(),
            densities[k].to_bits(),
            "{} {}",
            wo[k],
            wis[k]
        );
        assert_eq!(
            portable[k].to_bits(),
            densities[k].to_bits(),
            "{} {}",
            wo[k],
            wis[k]
        );
    }
    // A shorter `out` leaves the rest alone.
    let mut short = vec![
        Some(BxdfSample {
            wi: Vec3::Z,
            pdf: -1.0
        });
        3
    ];
    s.sample_each(&wo[..2], &u, &mut short);
    assert_eq!(short[2].map(|d| d.pdf), Some(-1.0));
}

/// The blend's slice k is the number of inner breakpoints whose cosine is
/// at or above cos θ_o, as a plain search counts it, for 1 to 130
/// breakpoints (the counts run 8 at a time over padded lists), at the
/// breakpoints themselves and between them, with and without the AVX2
/// token (the masks' runs).
#[test]
fn blend_slice_is_the_plain_count() {
    for count in [1usize, 2, 3, 9, 10, 17, 64, 130] {
        let u: Vec<f32> = (0..count)
            .map(|i| i as f32 / (count - 1).max(1) as f32)
            .collect();
        let blend = ThetaOBlend::new(&u);
        let cos = cos_theta_o(&u);
        let inner = &cos[1..cos.len().saturating_sub(1).max(1)];
        let mut zs: Vec<f32> = cos.clone();
        zs.extend((0..=200).map(|i| i as f32 / 200.0));
        for z in zs {
            let want = if count < 2 {
                0
            } else {
                inner.iter().filter(|&&c| c >= z).count()
            };
            assert_eq!(blend.at(None, z).0, want, "{count} breakpoints, z = {z}");
            #[cfg(target_arch = "x86_64")]
            if let Some(cpu) = acdf_core::cpu::avx2() {
                assert_eq!(
                    blend.at(Some(cpu), z).0,
                    want,
                    "{count} breakpoints, z = {z}"
                );
            }
        }
    }
}

/// The blend weight is linear in cos θ_o between two breakpoints, 0 and 1
/// at their ends, and the blended weights of the slices are continuous
/// across a breakpoint; the normal, the grazing end, NaN and a lone
/// breakpoint give valid pairs.
#[test]
fn blend_weights_follow_cos_theta_o() {
    let u = [0.0, 0.3, 0.7, 1.0];
    let blend = ThetaOBlend::new(&u);
    let cos = cos_theta_o(&u);
    assert_eq!(blend.at(None, 1.0), (0, 0.0));
    assert_eq!(blend.at(None, GRAZING_COS), (2, 1.0));
    assert_eq!(blend.at(None, 0.0), (2, 1.0));
    assert_eq!(blend.at(None, f32::NAN), (0, 0.0));
    assert_eq!(ThetaOBlend::new(&[0.0]).at(None, 0.5), (0, 0.0));
    // Halfway in cos θ_o between breakpoints 1 and 2.
    let z = 0.5 * (cos[1] + cos[2]);
    let (k, t) = blend.at(None, z);
    assert_eq!(k, 1);
    assert!((t - 0.5).abs() < 1e-5, "{t}");
    assert!((t - cos_weight(cos[1], cos[2], z)).abs() < 1e-6);
    // The weight of each slice on either side of breakpoint 1.
    let weights = |z: f32| {
        let (k, t) = blend.at(None, z);
        let mut w = [0.0f32; 4];
        w[k] += 1.0 - t;
        w[k + 1] += t;
        w
    };
    for (a, b) in weights(cos[1] + 1e-6).iter().zip(weights(cos[1] - 1e-6)) {
        assert!((a - b).abs() < 1e-3, "{a} {b}");
    }
    let at = weights(cos[1]);
    assert!((at[1] - 1.0).abs() < 1e-5, "{at:?}");
}

/// Under the cap, a capped build lowers its tolerance while it still fits:
/// it ends at or below the cap, with a lower tolerance than it started
/// from, and one more step down would not fit (or the tries are spent).
#[test]
fn room_under_the_cap_is_spent_on_variance() {
    let res: Resolution = "8x1x64x16".parse().unwrap();
    let mut builder = OutgoingBuilder::by_name("chi2", Some(4e-2), 32).unwrap();
    let free = OutgoingSampler::new(nickel(), res, builder.clone()).unwrap();
    let cap = 2 * free.storage_bytes();
    builder.max_bytes = Some(cap);
    let filled = OutgoingSampler::new(nickel(), res, builder.clone()).unwrap();
    assert!(filled.storage_bytes() <= cap);
    assert!(filled.storage_bytes() > free.storage_bytes());
    let tolerance = filled.builder().tolerance;
    assert!(tolerance < 4e-2, "{tolerance}");
    let lowest = 4e-2 / FILL_STEP.powi(FILL_TRIES as i32);
    if tolerance > lowest * 1.0001 {
        let mut finer = filled.builder().clone();
        finer.max_bytes = None;
        finer.tolerance /= FILL_STEP;
        finer.budget /= FILL_STEP;
        let next = OutgoingSampler::new(nickel(), res, finer).unwrap();
        assert!(next.storage_bytes() > cap);
    }
}

/// Files of the earlier isotropic layouts are refused with a typed error
/// that gives the reason and says to build the sampler again: layout 1
/// (blends linear in u_o), layout 3 (each slice with its own vertices) and
/// layout 5 (every curve's end vertices stored).
#[test]
fn earlier_layouts_are_refused() {
    let s = small(nickel());
    for (layout, reason) in [
        (1, "linearly in u_o"),
        (3, "own vertices"),
        (5, "end vertices"),
    ] {
        let e = OutgoingSampler::from_bytes(&s.to_bytes_as(layout))
            .err()
            .expect("an earlier layout is refused");
        assert!(e.to_string().contains(reason), "{e}");
        assert!(e.to_string().contains("build the sampler again"), "{e}");
    }
    assert!(OutgoingSampler::from_bytes(&s.to_bytes_as(persist::OUTGOING_VERSION)).is_ok());
}

/// The density of the other slice at a draw is read at the drawn cell:
/// it equals, bit for bit, that slice's density found by searching the
/// point, for draws from every slice (the blend's shortcut is exact).
#[test]
fn the_other_slice_is_read_at_the_drawn_cell() {
    let s = small(acdf_materials::builtin("gray-plastic").unwrap());
    let g = s.slices();
    assert!(g.len() >= 3);
    let n = s.cells;
    let mut compared = 0;
    for drawn in 0..g.len() {
        for k in 0..200 {
            let u = ((k as f32 + 0.5) / 200.0, (k as f32 * 0.618_034).fract());
            let d = g.sample(drawn, u.0, u.1, n, (0.0, 0.0));
            for other in 0..g.len() {
                let (cell, _) = g.locate(d.p.0, d.p.1, n, (0.0, 0.0));
                let cell = cell.expect("a drawn point lies in a cell with mass");
                let read = g.density(other, &d.cell);
                assert_eq!(read.to_bits(), g.density(other, &cell).to_bits());
                assert_eq!(read.to_bits(), g.pdf(other, d.p.0, d.p.1, n).to_bits());
                compared += 1;
            }
            assert!(g.density(drawn, &d.cell) > 0.0);
        }
    }
    assert!(compared > 600);
}

/// Tables without mass: a zero slice among others takes the masses of the
/// grid table (made of the others' normalised tables), and all-zero
/// tables give one uniform cell;
/// the result is valid and its densities integrate to one.
#[test]
fn slices_without_mass_stay_valid() {
    let (nx, ny) = (8, 16);
    let ramp: Vec<f32> = (0..nx * ny).map(|i| (i % 7) as f32).collect();
    let spike: Vec<f32> = (0..nx * ny).map(|i| (i == 37) as u8 as f32 * 5.0).collect();
    let zero = vec![0.0f32; nx * ny];
    let simplifier = simplifier_by_name("chi2").unwrap();
    let cells = (nx as f32, ny as f32);
    let integral = |g: &SharedSlices, s: usize| -> f64 {
        let mut sum = 0.0f64;
        for i in 0..4 * ny {
            for j in 0..4 * nx {
                let (x, y) = (
                    (j as f32 + 0.5) / (4 * nx) as f32,
                    (i as f32 + 0.5) / (4 * ny) as f32,
                );
                sum += g.pdf(s, x, y, cells) as f64;
            }
        }
        sum / (16 * nx * ny) as f64
    };
    let g = SharedSlices::build(
        &[ramp.clone(), zero.clone(), spike.clone()],
        nx,
        ny,
        &*simplifier,
        1e-3,
    )
    .unwrap();
    g.validate(nx, ny).unwrap();
    for s in 0..3 {
        assert!(
            (integral(&g, s) - 1.0).abs() < 1e-3,
            "slice {s}: {}",
            integral(&g, s)
        );
    }
    // The zero slice has mass both where the ramp and where the spike has.
    let spike_at = ((37 % nx) as f32 + 0.5) / nx as f32;
    let spike_row = ((37 / nx) as f32 + 0.5) / ny as f32;
    assert!(g.pdf(1, spike_at, spike_row, cells) > 0.0);
    assert!(g.pdf(1, 0.3 / nx as f32, 0.5, cells) > 0.0);
    let none = SharedSlices::build(&[zero.clone(), zero], nx, ny, &*simplifier, 1e-3).unwrap();
    none.validate(nx, ny).unwrap();
    assert_eq!(none.marginal_vertex_count(), 2);
    assert!((none.pdf(0, 0.3, 0.7, cells) - 1.0).abs() < 1e-4);
}

/// The compact arrays a file stores give back the same slices; storage
/// counts exactly their bytes (the breakpoints apart), with neither end
/// vertex of any curve; a count or a length that does not match the grid
/// is an error, not a misread.
#[test]
fn compact_slices_round_trip_and_count_their_bytes() {
    let (nx, ny) = (8, 16);
    let simplifier = simplifier_by_name("chi2").unwrap();
    let s = small(nickel());
    // A ramp, a slice without mass and a single spike; then no mass at all.
    let tables: Vec<Vec<f32>> = (0..3)
        .map(|k| {
            (0..nx * ny)
                .map(|i| [(i % 7) as f32, 0.0, (i == 37) as u8 as f32 * 5.0][k])
                .collect()
        })
        .collect();
    let toy = SharedSlices::build(&tables, nx, ny, &*simplifier, 1e-3).unwrap();
    let none = SharedSlices::build(&tables[1..2], nx, ny, &*simplifier, 1e-3).unwrap();
    let (n_theta_h, n_phi_h) = s.half_vector_cells();
    for (g, n_x, n_y) in [
        (s.slices().clone(), n_phi_h, n_theta_h),
        (toy, nx, ny),
        (none, nx, ny),
    ] {
        let c = g.compact();
        let bytes = 2 * c.marginal_inner.len()
            + c.counts.len()
            + c.conditional_inner.len()
            + 2 * c.slice_inner.iter().map(Vec::len).sum::<usize>();
        assert_eq!(g.storage_bytes(), bytes);
        let (vertices, conditionals) = g.conditional_vertices();
        let full = 2
            * (2 * g.marginal_vertex_count() + g.len() * (g.marginal_vertex_count() + vertices))
            + vertices;
        // Each slice saves its curves' 2 + 2 conditionals end values, the
        // grid its end positions and its 16-bit offsets.
        assert!(
            bytes + 4 * g.len() * (1 + conditionals) <= full,
            "{bytes} of {full}"
        );
        assert_eq!(SharedSlices::from_compact(&c, n_x, n_y).unwrap(), g);
        let mut extra = c.clone();
        extra.conditional_inner.push(1);
        assert!(SharedSlices::from_compact(&extra, n_x, n_y).is_err());
        let mut short = c.clone();
        short.slice_inner[0].push(1);
        assert!(SharedSlices::from_compact(&short, n_x, n_y).is_err());
        let mut counts = c.clone();
        counts.counts.push(0);
        assert!(SharedSlices::from_compact(&counts, n_x, n_y).is_err());
    }
    // A position past the cells of the axis is refused by the check of
    // the rebuilt curve.
    let mut c = small(nickel()).slices().compact();
    *c.conditional_inner
        .last_mut()
        .expect("inner conditional vertices") = u8::MAX;
    assert!(SharedSlices::from_compact(&c, n_phi_h, n_theta_h).is_err());
}

/// The lane kernels of the shared grid (`acdf_core::simd::shared_grid`) give the bits
/// of the one-at-a-time draw and density: on slices with a ramp, no mass
/// and a single spike, and on the built-in nickel at the default
/// resolution (longer curves, several lane steps), for u at 0 and next to
/// 1, points outside the unit square and NaN, every pair of slices and
/// blend weights 0 and 1 among them.
#[cfg(target_arch = "x86_64")]
#[test]
fn lane_draws_and_densities_equal_single_ones() {
    use acdf_core::search::lanes::STAGE;
    use acdf_core::simd::shared_grid::{DrawInputs, DrawnPoints};
    let Some(cpu) = acdf_core::cpu::avx2() else {
        println!("skipped: this CPU has no AVX2 and FMA (or ACDF_CPU=portable)");
        return;
    };
    let (nx, ny) = (8, 16);
    let ramp: Vec<f32> = (0..nx * ny).map(|i| (i % 7) as f32).collect();
    let spike: Vec<f32> = (0..nx * ny).map(|i| (i == 37) as u8 as f32 * 5.0).collect();
    let zero = vec![0.0f32; nx * ny];
    let simplifier = simplifier_by_name("chi2").unwrap();
    let toy = SharedSlices::build(&[ramp, zero, spike], nx, ny, &*simplifier, 1e-3).unwrap();
    let s = OutgoingSampler::new(
        nickel(),
        Resolution::default(),
        OutgoingBuilder::by_name("chi2", None, 128).unwrap(),
    )
    .unwrap();
    // Curves longer than the sixteen entries of one lane step.
    assert!(s.slices().marginal_vertex_count() > 16 && s.slices().len() > 4);
    let grids = [(toy, (nx as f32, ny as f32)), (s.slices().clone(), s.cells)];
    let mut state = 0x9e37_79b9_u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        (state >> 8) as f32 / (1u32 << 24) as f32
    };
    let bits = |v: f32| v.to_bits();
    for (g, cells) in &grids {
        let count = g.len() as i32;
        for round in 0..40 {
            let special = |l: usize, v: f32| match (round + l) % 11 {
                0 => 0.0,
                1 => acdf_core::ONE_MINUS_EPSILON,
                _ => v,
            };
            // Blends with t = 0, t = 1/2, t next to 1 and drawn ones, and
            // u.x on the boundary 1 - t between the two slices.
            let k: Vec<i32> = (0..STAGE)
                .map(|l| (l as i32 + round as i32) % count)
                .collect();
            let t: Vec<f32> = (0..STAGE)
                .map(|l| match l % 5 {
                    _ if k[l] + 1 == count => 0.0,
                    0 => 0.0,
                    1 => 0.5,
                    2 => acdf_core::ONE_MINUS_EPSILON,
                    _ => next(),
                })
                .collect();
            let u_x: Vec<f32> = (0..STAGE)
                .map(|l| match (round + l) % 11 {
                    2 if t[l] > 0.0 => 1.0 - t[l],
                    _ => special(l, next()),
                })
                .collect();
            let u_y: Vec<f32> = (0..STAGE).map(|l| special(l + 3, next())).collect();
            let (mut x, mut y, mut p, mut same) = (
                vec![0.0; STAGE],
                vec![0.0; STAGE],
                vec![0.0; STAGE],
                vec![0; STAGE],
            );
            let input = DrawInputs {
                k: &k,
                t: &t,
                u_x: &u_x,
                u_y: &u_y,
            };
            let out = DrawnPoints {
                x: &mut x,
                y: &mut y,
                p: &mut p,
                same: &mut same,
            };
            let lanes = g.lane_grid().expect("the arrays fit the lanes");
            assert!(lanes.sample_lanes(cpu, &input, *cells, CELL_MARGIN, out));
            for l in 0..STAGE {
                let u = Vec2::new(u_x[l], u_y[l]);
                let (drawn, other, ux, w) = super::pick_slice(k[l] as usize, t[l], u);
                let d = g.sample(drawn, ux, u.y, *cells, CELL_MARGIN);
                let mut want = w * g.density(drawn, &d.cell);
                if 1.0 - w > 0.0 {
                    want += (1.0 - w) * g.density(other, &d.cell);
                }
                assert_eq!(
                    (bits(x[l]), bits(y[l])),
                    (bits(d.p.0), bits(d.p.1)),
                    "lane {l}"
                );
                assert_eq!(
                    (bits(p[l]), same[l]),
                    (bits(want), -i32::from(d.same_around)),
                    "lane {l}"
                );
            }
            // Densities: points in and out of the square, NaN among them.
            let t: Vec<f32> = (0..STAGE)
                .map(|l| {
                    if k[l] + 1 < count && l % 3 != 0 {
                        special(l, next())
                    } else {
                        0.0
                    }
                })
                .collect();
            let pick = |l: usize, v: f32| match (round + 2 * l) % 13 {
                0 => f32::NAN,
                1 => -0.25,
                2 => 1.5,
                _ => special(l, v),
            };
            let px: Vec<f32> = (0..STAGE).map(|l| pick(l, next())).collect();
            let py: Vec<f32> = (0..STAGE).map(|l| pick(l + 5, next())).collect();
            let mut blended = vec![0.0; STAGE];
            let lanes = g.lane_grid().expect("the arrays fit the lanes");
            assert!(lanes.density_lanes(cpu, &k, &t, &px, &py, *cells, &mut blended));
            for l in 0..STAGE {
                let mut want = 0.0;
                if let (Some(cell), _) = g.locate(px[l], py[l], *cells, (0.0, 0.0)) {
                    if t[l] < 1.0 {
                        want += (1.0 - t[l]) * g.density(k[l] as usize, &cell);
                    }
                    if t[l] > 0.0 {
                        want += t[l] * g.density(k[l] as usize + 1, &cell);
                    }
                }
                assert_eq!(
                    bits(blended[l]),
                    bits(want),
                    "lane {l}: ({}, {})",
                    px[l],
                    py[l]
                );
            }
        }
    }
}

/// The number of CDF values a file stores for its last slice.
fn last_slice_values(bytes: &[u8]) -> usize {
    let s = OutgoingSampler::from_bytes(bytes).unwrap();
    s.slices().compact().slice_inner.last().unwrap().len()
}

/// An edit of a sampler's offsets and slice CDF values.
type Edit = dyn Fn(&mut Vec<u16>, &mut Vec<Vec<u16>>);

/// A well-sealed file whose slices lie is refused with a typed error
/// naming the field: a slice one CDF value short, a slice whose marginal
/// CDF runs backwards, a segment with mass but without a conditional.
#[test]
fn hostile_files_are_typed_errors() {
    let field_of = |bytes: Vec<u8>| match OutgoingSampler::from_bytes(&bytes) {
        Err(acdf_tabulated::persist::PersistError::Invalid { field, .. }) => field,
        Err(other) => panic!("unexpected {other}"),
        Ok(_) => panic!("a lying file loaded"),
    };
    let rebuilt = |edit: &Edit| {
        let mut s = small(nickel());
        let g = s.slices.clone();
        let mut offsets = g.offsets().to_vec();
        let mut cdfs: Vec<Vec<u16>> = (0..g.len()).map(|k| g.slice_cdf(k).to_vec()).collect();
        edit(&mut offsets, &mut cdfs);
        s.slices = SharedSlices::from_arrays(
            g.marginal_pos(),
            &offsets,
            g.conditional_pos().to_vec(),
            &cdfs,
        );
        s.to_bytes()
    };
    // The last slice one value short: its count and its bytes cut, and
    // the file sealed again.
    let good = rebuilt(&|_, _| {});
    let mut body = acdf_tabulated::persist::open(&good).unwrap().to_vec();
    let last = last_slice_values(&good);
    let at = body.len() - 2 * last - 4;
    body[at..at + 4].copy_from_slice(&(last as u32 - 1).to_le_bytes());
    body.truncate(body.len() - 2);
    assert_eq!(field_of(acdf_tabulated::persist::seal(&body)), "slices");
    assert_eq!(
        field_of(rebuilt(&|_, c| {
            let last = c[1].len() - 1;
            c[1].swap(1, last);
        })),
        "slices"
    );
    assert_eq!(field_of(rebuilt(&|o, _| o[1] = o[0])), "slices");
    assert!(OutgoingSampler::from_bytes(&rebuilt(&|_, _| {})).is_ok());
}
