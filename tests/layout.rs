//! Host/shader layout agreement: every struct's member offsets and size, every
//! storage array's stride, the bindings' kinds, and the constants both sides
//! share, read from the shader by naga and compared with src/layout/.

use std::mem::{offset_of, size_of};

use ash::vk;
use glint::cpu::Real;
use glint::layout::*;
use naga::{AddressSpace, ArraySize, Expression, Literal, Module, TypeInner};

fn shader() -> Module {
    naga::front::wgsl::parse_str(glint::gpu::shader::TRACE_WGSL).expect("shader parses")
}

/// (member name, offset) pairs and the size of the shader struct `name`.
fn shader_struct(module: &Module, name: &str) -> (Vec<(String, u32)>, u32) {
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("shader has no struct {name}"));
    match &ty.1.inner {
        TypeInner::Struct { members, span } => (
            members
                .iter()
                .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                .collect(),
            *span,
        ),
        other => panic!("{name} is not a struct: {other:?}"),
    }
}

macro_rules! check_struct {
    ($module:expr, $wgsl:literal, $rust:ty, [$($field:ident),* $(,)?]) => {{
        let (members, span) = shader_struct(&$module, $wgsl);
        let rust: Vec<(String, u32)> =
            vec![$((stringify!($field).to_string(), offset_of!($rust, $field) as u32)),*];
        assert_eq!(members, rust, "member names/offsets of {} vs {}", $wgsl, stringify!($rust));
        assert_eq!(span as usize, size_of::<$rust>(), "size of {} vs {}", $wgsl, stringify!($rust));
    }};
}

#[test]
fn structs_match() {
    let m = shader();
    check_struct!(
        m,
        "Frame",
        GpuFrame,
        [
            background,
            ambient,
            half_extent,
            size,
            node_count,
            light_count,
            sphere_count,
            seed,
            spp,
            shadow_samples,
            reflect_depth,
            shutter,
            chunk_shift,
            addresses,
            sampling,
            _pad0,
            _pad
        ]
    );
    check_struct!(m, "Tile", GpuTile, [origin, size, budget, first, _pad]);
    check_struct!(
        m,
        "PixelState",
        GpuPixelState,
        [
            sum,
            sample,
            color,
            bounce,
            weight,
            light,
            shade,
            area_sample,
            area,
            prim,
            origin,
            t,
            dir,
            b1,
            time,
            b2,
            phase,
            _pad
        ]
    );
    check_struct!(
        m,
        "Status",
        GpuStatus,
        [remaining, cut, first_cut, closest_rays, shadow_rays, _pad]
    );
    check_struct!(
        m,
        "Sphere",
        GpuSphere,
        [center, radius, kd, shininess, ks, _pad]
    );
    check_struct!(m, "Triangle", GpuTriangle, [v]);
    check_struct!(m, "TriangleNormals", GpuTriangleNormals, [n]);
    check_struct!(m, "Material", GpuMaterial, [kd, shininess, ks, _pad]);
    check_struct!(
        m,
        "Light",
        GpuLight,
        [position, kind, color, radius, edge_u, skip_first, edge_v, skip_count, velocity, _pad2]
    );
    check_struct!(m, "WideNode", GpuWideNode, [origin, lo_hi, hi_yz, child]);
}

#[test]
fn bindings_match_the_pipeline_and_array_strides_match_rust() {
    let m = shader();
    // Element sizes of the storage arrays, by binding.
    let mut strides = vec![
        (2, size_of::<GpuSphere>()),
        (3, size_of::<GpuTriangle>()),
        (4, size_of::<GpuTriangleNormals>()),
        (5, size_of::<GpuLight>()),
        (6, size_of::<GpuWideNode>()),
        (7, size_of::<u32>()),
        (8, 16),
        (9, 16),
        (10, size_of::<GpuPixelState>()),
        (12, size_of::<GpuMaterial>()),
        (13, size_of::<u32>()),
    ];
    // A uniform copy's array holds its list's elements, or vec4s of words.
    for j in 0..UNIFORM_LISTS.len() {
        strides.push((UNIFORM_FIRST + j, uniform_copy_element_bytes(j)));
    }
    // A split list's extra chunks hold what its first binding holds.
    for (j, &(first, _)) in SPLIT_LISTS.iter().enumerate() {
        let stride = strides.iter().find(|s| s.0 == first).expect("listed").1;
        for k in 1..SPLIT_CHUNKS {
            strides.push((SPLIT_FIRST + (SPLIT_CHUNKS - 1) * j + k - 1, stride));
        }
    }
    let mut seen = Vec::new();
    let mut element = Vec::new();
    for (_, var) in m.global_variables.iter() {
        let Some(binding) = &var.binding else {
            continue;
        };
        assert_eq!(binding.group, 0);
        if binding.binding == glint::gpu::shader::DEVICE_MEMORY_BINDING {
            // Never bound: only the loads through device addresses read it,
            // and those are rewritten before the driver sees them.
            assert_eq!(binding.binding as usize, glint::gpu::BINDINGS.len());
            assert!(matches!(var.space, AddressSpace::Storage { .. }));
            continue;
        }
        let i = binding.binding as usize;
        let expected = match var.space {
            AddressSpace::Uniform => vk::DescriptorType::UNIFORM_BUFFER,
            AddressSpace::Storage { .. } => vk::DescriptorType::STORAGE_BUFFER,
            other => panic!("unexpected address space {other:?}"),
        };
        assert_eq!(glint::gpu::BINDINGS[i], expected, "binding {i}");
        if let TypeInner::Array { stride, base, size } = m.types[var.ty].inner {
            element.push((i, base));
            // A uniform copy's fixed length is the one the host pads it to.
            if let Some(j) = i.checked_sub(UNIFORM_FIRST) {
                let ArraySize::Constant(len) = size else {
                    panic!("binding {i} is a uniform copy: a fixed-length array");
                };
                assert_eq!(
                    u64::from(len.get()),
                    uniform_list_len(j),
                    "length of binding {i}"
                );
            }
            let want = strides
                .iter()
                .find(|s| s.0 == i)
                .expect("known array binding")
                .1;
            assert_eq!(stride as usize, want, "array stride of binding {i}");
        }
        seen.push(i);
    }
    seen.sort();
    assert_eq!(seen, (0..glint::gpu::BINDINGS.len()).collect::<Vec<_>>());
    let element_of = |b: usize| element.iter().find(|e| e.0 == b).expect("an array").1;
    for (j, &(list, name)) in UNIFORM_LISTS.iter().enumerate() {
        let copy = UNIFORM_FIRST + j;
        let list_stride = strides.iter().find(|s| s.0 == list).expect("listed").1;
        if uniform_copy_element_bytes(j) == list_stride {
            assert_eq!(
                element_of(copy),
                element_of(list),
                "binding {copy} copies {name}"
            );
            continue;
        }
        // Words, four to a vector: the list's own scalars where it holds
        // scalars (references), 32-bit ones where it holds structs.
        let TypeInner::Vector { size, scalar } = m.types[element_of(copy)].inner else {
            panic!("binding {copy} holds {name} as vectors of words");
        };
        assert_eq!((size as usize, scalar.width), (4, 4), "binding {copy}");
        if let TypeInner::Scalar(s) = m.types[element_of(list)].inner {
            assert_eq!(scalar, s, "binding {copy} packs {name}");
        }
    }
    for (j, &(first, name)) in SPLIT_LISTS.iter().enumerate() {
        for k in 1..SPLIT_CHUNKS {
            let chunk = SPLIT_FIRST + (SPLIT_CHUNKS - 1) * j + k - 1;
            assert_eq!(
                element_of(chunk),
                element_of(first),
                "binding {chunk} is chunk {k} of {name}"
            );
        }
    }
}

fn constant(m: &Module, name: &str) -> Literal {
    let (_, c) = m
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("shader has no const {name}"));
    match m.global_expressions[c.init] {
        Expression::Literal(l) => l,
        ref e => panic!("{name} is not a literal: {e:?}"),
    }
}

fn f32_const(m: &Module, name: &str) -> f32 {
    match constant(m, name) {
        Literal::F32(v) => v,
        Literal::AbstractFloat(v) => v as f32,
        l => panic!("{name} is not a float: {l:?}"),
    }
}

#[test]
fn shared_constants_match() {
    let m = shader();
    assert_eq!(constant(&m, "SPHERE_BIT"), Literal::U32(SPHERE_BIT));
    assert_eq!(constant(&m, "BVH_MAX_DEPTH"), Literal::U32(BVH_MAX_DEPTH));
    assert_eq!(
        constant(&m, "TRAVERSAL_STACK"),
        Literal::U32(TRAVERSAL_STACK)
    );
    assert_eq!(constant(&m, "WIDE_LEAF"), Literal::U32(WIDE_LEAF));
    assert_eq!(constant(&m, "WIDE_EMPTY"), Literal::U32(WIDE_EMPTY));
    assert_eq!(constant(&m, "LEAF_END"), Literal::U32(LEAF_END));
    assert_eq!(
        constant(&m, "LEAF_COUNT_SHIFT"),
        Literal::U32(LEAF_COUNT_SHIFT)
    );
    assert_eq!(
        constant(&m, "LEAF_COUNT_MASK"),
        Literal::U32(LEAF_COUNT_MASK)
    );
    assert_eq!(constant(&m, "WORKGROUP_SIZE"), Literal::U32(WORKGROUP_SIZE));
    assert_eq!(
        constant(&m, "NO_HIT"),
        Literal::U32(glint::cpu::trace::NO_HIT)
    );
    assert_eq!(constant(&m, "NO_HIT"), Literal::U32(glint::probe::NO_HIT));
    assert_eq!(
        constant(&m, "FLAG_NONFINITE_COLOR"),
        Literal::U32(FLAG_NONFINITE_COLOR)
    );
    assert_eq!(
        constant(&m, "FLAG_NONFINITE_SURFACE"),
        Literal::U32(FLAG_NONFINITE_SURFACE)
    );
    assert_eq!(constant(&m, "PATH_HEADER"), Literal::U32(PATH_HEADER));
    assert_eq!(
        constant(&m, "SPLIT_CHUNKS"),
        Literal::U32(SPLIT_CHUNKS as u32)
    );
    assert_eq!(
        constant(&m, "MAX_TRAVERSAL_STEPS"),
        Literal::U32(MAX_TRAVERSAL_STEPS)
    );
    assert_eq!(constant(&m, "PATH_PER_LIGHT"), Literal::U32(PATH_PER_LIGHT));
    assert_eq!(constant(&m, "LIGHT_POINT"), Literal::U32(LIGHT_POINT));
    assert_eq!(constant(&m, "LIGHT_SPHERE"), Literal::U32(LIGHT_SPHERE));
    assert_eq!(constant(&m, "LIGHT_RECT"), Literal::U32(LIGHT_RECT));
    use glint::cpu::sample;
    assert_eq!(
        constant(&m, "STREAM_PIXEL"),
        Literal::U32(sample::STREAM_PIXEL)
    );
    assert_eq!(
        constant(&m, "STREAM_TIME"),
        Literal::U32(sample::STREAM_TIME)
    );
    assert_eq!(
        constant(&m, "STREAM_LIGHT"),
        Literal::U32(sample::STREAM_LIGHT)
    );
    assert_eq!(constant(&m, "ROTATION"), Literal::U32(sample::ROTATION));
    assert_eq!(
        constant(&m, "SAMPLER_STRATIFIED"),
        Literal::U32(SAMPLER_STRATIFIED)
    );
    assert_eq!(constant(&m, "SAMPLER_SOBOL"), Literal::U32(SAMPLER_SOBOL));
    // Compared as bits: the CPU f32 twin must use the shader's exact values.
    let pairs = [
        ("T_INF", <f32 as Real>::T_INF),
        ("BOX_T_SCALE", <f32 as Real>::BOX_T_SCALE),
        ("MIN_DIR", <f32 as Real>::MIN_DIR),
        ("OFFSET_ORIGIN", <f32 as Real>::OFFSET_ORIGIN),
        ("OFFSET_FLOAT_SCALE", <f32 as Real>::OFFSET_FLOAT_SCALE),
        ("OFFSET_INT_SCALE", <f32 as Real>::OFFSET_INT_SCALE),
        ("NAIVE_OFFSET", <f32 as Real>::NAIVE_OFFSET),
        ("NAIVE_DET_EPSILON", <f32 as Real>::NAIVE_DET_EPSILON),
    ];
    for (name, rust) in pairs {
        assert_eq!(f32_const(&m, name).to_bits(), rust.to_bits(), "{name}");
    }
    let band = glint::bvh::lights_on_surfaces::TANGENT_BAND;
    assert_eq!(f64::from(f32_const(&m, "TANGENT_BAND")), band);
    let on_surface = glint::bvh::lights_on_surfaces::ON_SURFACE;
    assert_eq!(f64::from(f32_const(&m, "ON_SURFACE")), on_surface);
}

/// The window's resolve shader (`gpu::present`) takes `GpuResolve`.
#[test]
fn resolve_parameters_match() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/shaders/resolve.wgsl");
    let source = std::fs::read_to_string(path).expect("read resolve shader");
    let m = naga::front::wgsl::parse_str(&source).expect("resolve shader parses");
    check_struct!(m, "Resolve", GpuResolve, [size, reset, bgra]);
}
