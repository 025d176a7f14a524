//! The trace shader, specialised per (methods, feature set) at run time:
//! WGSL parsed once, every `override` resolved by naga's `process_overrides`
//! (Vulkan specialization constants never reach naga's SPIR-V), then every
//! `if (FEATURE)` on a resolved constant replaced by the branch it takes,
//! unreachable functions dropped, the module validated again and written as
//! SPIR-V. A feature that is off is thus absent from the SPIR-V, not merely
//! skipped, so the driver compiles (and the GPU runs) only what the scene
//! calls for.

use std::collections::HashSet;
use std::sync::OnceLock;

use naga::back::spv;
use naga::proc::{BoundsCheckPolicies, BoundsCheckPolicy};
use naga::valid::{Capabilities, ModuleInfo, ValidationFlags, Validator};
use naga::{Block, Expression, Function, Handle, Literal, Module, Statement};

use super::bindings::Lists;
pub use super::error::ShaderError;
pub use super::rewrite::DEVICE_MEMORY_BINDING;
use super::rewrite::{device_loads, no_contraction, unfill_local_arrays};
use crate::features::Features;
use crate::methods::Methods;

/// Declares the shader's pieces once: their names, their texts, and the
/// source they join into.
macro_rules! trace_pieces {
    ($($name:literal),+ $(,)?) => {
        /// The shader's pieces, by concept, each beside its CPU twin, in the
        /// order they are joined (a plain join: WGSL declarations may come
        /// in any order, and each piece is whole declarations).
        pub const TRACE_PIECES: &[&str] = &[$($name),+];

        /// The shader source: the pieces joined, compiled into the binary.
        pub const TRACE_WGSL: &str =
            concat!($(include_str!(concat!("../../shaders/trace/", $name, ".wgsl"))),+);

        /// Each piece's text, in `TRACE_PIECES`' order.
        const TRACE_PIECE_TEXTS: &[&str] =
            &[$(include_str!(concat!("../../shaders/trace/", $name, ".wgsl"))),+];
    };
}

trace_pieces!("layout", "sample", "hit", "scene", "traverse", "shade", "kernel");
const TRACE_PATH: &str = "shaders/trace/*.wgsl, joined";

/// Where line `line` (1-based) of `TRACE_WGSL` comes from: the piece's
/// file and its line there, for messages.
pub fn trace_source_line(line: usize) -> Option<(String, usize)> {
    let mut first = 1;
    for (name, text) in TRACE_PIECES.iter().zip(TRACE_PIECE_TEXTS) {
        let lines = text.matches('\n').count();
        if line < first + lines {
            return Some((format!("shaders/trace/{name}.wgsl"), line - first + 1));
        }
        first += lines;
    }
    None
}

/// A naga message about the joined source, with the piece it points into.
fn located(message: String, line: Option<usize>) -> String {
    match line.and_then(trace_source_line) {
        Some((file, at)) => format!("{message}\n(at {file}:{at})"),
        None => message,
    }
}

pub(crate) fn parsed() -> Result<&'static (Module, ModuleInfo), ShaderError> {
    static PARSED: OnceLock<Result<(Module, ModuleInfo), ShaderError>> = OnceLock::new();
    PARSED
        .get_or_init(|| {
            let fail = |message| ShaderError {
                what: "parse".into(),
                message,
            };
            let module = naga::front::wgsl::parse_str(TRACE_WGSL).map_err(|e| {
                let line = e.location(TRACE_WGSL).map(|l| l.line_number as usize);
                fail(located(
                    e.emit_to_string_with_path(TRACE_WGSL, TRACE_PATH),
                    line,
                ))
            })?;
            let info = validator().validate(&module).map_err(|e| {
                let line = e
                    .spans()
                    .next()
                    .map(|(span, _)| span.location(TRACE_WGSL).line_number as usize);
                fail(located(
                    e.emit_to_string_with_path(TRACE_WGSL, TRACE_PATH),
                    line,
                ))
            })?;
            Ok((module, info))
        })
        .as_ref()
        .map_err(Clone::clone)
}

fn validator() -> Validator {
    Validator::new(ValidationFlags::all(), Capabilities::empty())
}

/// What the packed data, not the scene's effects, asks of the shader.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Variant {
    /// How the lists are bound: split over several bindings
    /// (`layout::SPLIT_LISTS`), or read from their uniform copies
    /// (`layout::UNIFORM_LISTS`).
    pub lists: Lists,
    /// Some point light lies on a surface (`lights_on_surfaces`).
    pub light_skips: bool,
    /// With uniform lists: the triangle copy holds corners only
    /// (`layout::CopyForm::Corners`).
    pub corners: bool,
    /// Reference slot r holds triangle r (`GpuScene::scene_triangles`).
    pub leaf_order: bool,
    /// A tile's first pass without pixel state (`ONE_PASS` in the shader).
    pub one_pass: bool,
}

/// The override values of a variant, as `process_overrides` takes them.
pub fn pipeline_constants(
    methods: Methods,
    features: Features,
    variant: Variant,
) -> naga::back::PipelineConstants {
    let mut constants = naga::back::PipelineConstants::default();
    let flag = |on: bool| if on { 1.0 } else { 0.0 };
    constants.insert("ROBUST".into(), flag(methods == Methods::Robust));
    constants.insert("SPLIT".into(), flag(variant.lists == Lists::Split));
    constants.insert(
        "UNIFORM_LISTS".into(),
        flag(variant.lists == Lists::Uniform),
    );
    constants.insert("ADDRESSES".into(), flag(variant.lists == Lists::Address));
    constants.insert("LIGHT_SKIPS".into(), flag(variant.light_skips));
    constants.insert(
        "UNIFORM_CORNERS".into(),
        flag(variant.lists == Lists::Uniform && variant.corners),
    );
    constants.insert("LEAF_ORDER".into(), flag(variant.leaf_order));
    constants.insert("ONE_PASS".into(), flag(variant.one_pass));
    for (name, on) in features.overrides() {
        constants.insert(name.into(), flag(on));
    }
    constants
}

/// The module with its overrides resolved and dead feature branches removed,
/// validated.
pub fn specialize(
    methods: Methods,
    features: Features,
    variant: Variant,
) -> Result<(Module, ModuleInfo), ShaderError> {
    let (module, info) = parsed()?;
    let what = format!(
        "{} methods, features {}{}{}{}",
        methods.name(),
        features.label(),
        match variant.lists {
            Lists::Plain => "",
            Lists::Split => ", split lists",
            Lists::Uniform if variant.corners => ", uniform lists (corners)",
            Lists::Uniform => ", uniform lists",
            Lists::Address => ", address lists",
        },
        if variant.light_skips {
            ", lights on surfaces"
        } else {
            ""
        },
        if variant.one_pass { ", one pass" } else { "" }
    );
    let fail = |message: String| ShaderError {
        what: what.clone(),
        message,
    };
    let constants = pipeline_constants(methods, features, variant);
    let (resolved, _) =
        naga::back::pipeline_constants::process_overrides(module, info, None, &constants)
            .map_err(|e| fail(format!("resolving overrides: {e}")))?;
    let mut module = resolved.into_owned();
    let constants = Constants {
        constants: &module.constants,
        init: &module.global_expressions,
    };
    for (_, f) in module.functions.iter_mut() {
        prune_function(f, &constants);
    }
    for ep in &mut module.entry_points {
        prune_function(&mut ep.function, &constants);
    }
    naga::compact::compact(&mut module, naga::compact::KeepUnused::No);
    let info = validator()
        .validate(&module)
        .map_err(|e| fail(format!("validation after specialisation: {e:?}")))?;
    Ok((module, info))
}

/// SPIR-V words of the specialised shader, all entry points.
pub fn spirv(
    methods: Methods,
    features: Features,
    variant: Variant,
) -> Result<Vec<u32>, ShaderError> {
    let (module, info) = specialize(methods, features, variant)?;
    let options = spv::Options {
        // SPIR-V 1.0 runs on every Vulkan 1.0 device, MoltenVK included.
        lang_version: (1, 0),
        flags: spv::WriterFlags::empty(),
        // Every index the shader uses comes from our own BVH builder; Restrict
        // (clamp) still keeps a builder bug from reading out of bounds, at the
        // cost of a min() per access (not measurable on lavapipe).
        bounds_check_policies: BoundsCheckPolicies {
            index: BoundsCheckPolicy::Restrict,
            buffer: BoundsCheckPolicy::Restrict,
            image_load: BoundsCheckPolicy::Restrict,
            binding_array: BoundsCheckPolicy::Restrict,
        },
        // A loop the compiler may assume finite must be finite; naga's counter
        // makes that hold even for a traversal bug, which the host's fence
        // timeout then reports instead of a hung device. Measured cost on
        // lavapipe: ~8% of SIGGRAPH's median render (553 vs 599 ms), inside
        // the run-to-run spread.
        force_loop_bounding: true,
        // Without a binding map naga writes each @group/@binding as declared.
        fake_missing_bindings: true,
        ..spv::Options::default()
    };
    let words = spv::write_vec(&module, &info, &options, None).map_err(|e| ShaderError {
        what: format!("{} methods, features {}", methods.name(), features.label()),
        message: format!("SPIR-V generation: {e}"),
    })?;
    let words = no_contraction(&unfill_local_arrays(&words));
    Ok(if variant.lists == Lists::Address {
        device_loads(&words)
    } else {
        words
    })
}

/// The module's constants and their initialisers, borrowed beside its
/// functions (which pruning mutates).
struct Constants<'a> {
    constants: &'a naga::Arena<naga::Constant>,
    init: &'a naga::Arena<Expression>,
}

/// The value of a condition that process_overrides made constant.
fn const_bool(expr: Handle<Expression>, f: &Function, m: &Constants) -> Option<bool> {
    match f.expressions[expr] {
        Expression::Literal(Literal::Bool(b)) => Some(b),
        Expression::Constant(c) => match m.init[m.constants[c].init] {
            Expression::Literal(Literal::Bool(b)) => Some(b),
            _ => None,
        },
        _ => None,
    }
}

fn prune_function(f: &mut Function, m: &Constants) {
    let body = std::mem::take(&mut f.body);
    f.body = prune_block(body, f, m);
    // A `let` whose defining statement went with a removed branch names an
    // expression nothing evaluates any more; compaction keeps named
    // expressions alive, so drop those names first.
    let mut defined = HashSet::new();
    defined_expressions(&f.body, &mut defined);
    let exprs = &f.expressions;
    f.named_expressions
        .retain(|h, _| exprs[*h].needs_pre_emit() || defined.contains(h));
}

/// Expressions the statements of `block` evaluate: emitted ranges and
/// call results (the only result-bearing statements the shader uses).
fn defined_expressions(block: &Block, out: &mut HashSet<Handle<Expression>>) {
    for statement in block.iter() {
        match statement {
            Statement::Emit(range) => out.extend(range.clone()),
            Statement::Call {
                result: Some(r), ..
            } => {
                out.insert(*r);
            }
            Statement::Block(b) => defined_expressions(b, out),
            Statement::If { accept, reject, .. } => {
                defined_expressions(accept, out);
                defined_expressions(reject, out);
            }
            Statement::Loop {
                body, continuing, ..
            } => {
                defined_expressions(body, out);
                defined_expressions(continuing, out);
            }
            Statement::Switch { cases, .. } => {
                for c in cases {
                    defined_expressions(&c.body, out);
                }
            }
            _ => {}
        }
    }
}

fn prune_block(block: Block, f: &Function, m: &Constants) -> Block {
    let mut out = Block::new();
    for (statement, span) in block.span_into_iter() {
        let statement = match statement {
            Statement::If {
                condition,
                accept,
                reject,
            } => match const_bool(condition, f, m) {
                Some(true) => Statement::Block(prune_block(accept, f, m)),
                Some(false) => Statement::Block(prune_block(reject, f, m)),
                None => Statement::If {
                    condition,
                    accept: prune_block(accept, f, m),
                    reject: prune_block(reject, f, m),
                },
            },
            Statement::Block(b) => Statement::Block(prune_block(b, f, m)),
            Statement::Loop {
                body,
                continuing,
                break_if,
            } => Statement::Loop {
                body: prune_block(body, f, m),
                continuing: prune_block(continuing, f, m),
                break_if,
            },
            Statement::Switch { selector, cases } => Statement::Switch {
                selector,
                cases: cases
                    .into_iter()
                    .map(|mut c| {
                        c.body = prune_block(std::mem::take(&mut c.body), f, m);
                        c
                    })
                    .collect(),
            },
            other => other,
        };
        out.push(statement, span);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The joined source is the pieces in order, and a line of it is
    /// traced back to its piece: each piece's own header comment is its
    /// first line.
    #[test]
    fn the_pieces_join_in_order_and_lines_find_their_piece() {
        let texts = TRACE_PIECE_TEXTS;
        assert_eq!(TRACE_WGSL, texts.concat());
        assert_eq!(TRACE_PIECES.len(), texts.len());
        let mut line = 1;
        for (name, text) in TRACE_PIECES.iter().zip(texts) {
            let file = format!("shaders/trace/{name}.wgsl");
            assert_eq!(trace_source_line(line), Some((file.clone(), 1)));
            if *name != "layout" {
                assert!(text.starts_with(&format!("// {file}:")), "{file}");
            }
            let lines = text.matches('\n').count();
            assert_eq!(trace_source_line(line + lines - 1), Some((file, lines)));
            line += lines;
        }
        assert_eq!(trace_source_line(line), None);
    }

    fn function_names(m: &Module) -> Vec<String> {
        m.functions
            .iter()
            .filter_map(|(_, f)| f.name.clone())
            .collect()
    }

    #[test]
    fn features_that_are_off_leave_the_shader() {
        let plain = Features {
            spheres: true,
            triangles: true,
            ..Features::default()
        };
        let (m, _) = specialize(Methods::Robust, plain, Variant::default()).unwrap();
        let names = function_names(&m);
        for gone in [
            "area_term",
            "light_sample_point",
            "reflect_off",
            "stratified_2d",
            "hit_sphere_naive",
            "hit_triangle_naive",
        ] {
            assert!(!names.iter().any(|n| n == gone), "{gone} in {names:?}");
        }
        let (all, _) = specialize(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        let names = function_names(&all);
        for kept in [
            "area_term",
            "light_sample_point",
            "reflect_off",
            "stratified_2d",
        ] {
            assert!(names.iter().any(|n| n == kept), "{kept} missing: {names:?}");
        }
    }

    /// Names of the global variables that `pick` finds in the expressions
    /// of any function or entry point, sorted, each once.
    fn global_names(
        m: &Module,
        pick: impl Fn(&Function, &Expression) -> Option<Handle<naga::GlobalVariable>>,
    ) -> Vec<String> {
        let functions = m.functions.iter().map(|(_, f)| f);
        let mut names: Vec<String> = functions
            .chain(m.entry_points.iter().map(|ep| &ep.function))
            .flat_map(|f| f.expressions.iter().map(move |(_, e)| (f, e)))
            .filter_map(|(f, e)| pick(f, e))
            .filter_map(|g| m.global_variables[g].name.clone())
            .collect();
        names.sort();
        names.dedup();
        names
    }

    /// Names of the global variables any function or entry point reads.
    fn globals_used(m: &Module) -> Vec<String> {
        global_names(m, |_, e| match *e {
            Expression::GlobalVariable(g) => Some(g),
            _ => None,
        })
    }

    /// Names of the global variables some function or entry point indexes
    /// (reads or writes an element of), not only takes the length of.
    fn globals_indexed(m: &Module) -> Vec<String> {
        global_names(m, |f, e| match *e {
            Expression::Access { base, .. } | Expression::AccessIndex { base, .. } => {
                match f.expressions[base] {
                    Expression::GlobalVariable(g) => Some(g),
                    _ => None,
                }
            }
            _ => None,
        })
    }

    /// The one-pass shader neither reads nor writes the pixel state (the
    /// point of it); the resumable one does both.
    #[test]
    fn only_the_resumable_shader_touches_the_pixel_state() {
        let (resumable, _) =
            specialize(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        assert!(globals_used(&resumable).iter().any(|n| n == "state"));
        let variant = Variant {
            one_pass: true,
            ..Variant::default()
        };
        let (one_pass, _) = specialize(Methods::Robust, Features::ALL, variant).unwrap();
        let used = globals_used(&one_pass);
        assert!(!used.iter().any(|n| n == "state"), "{used:?}");
        assert!(used.iter().any(|n| n == "status"), "{used:?}");
    }

    #[test]
    fn only_a_split_shader_reads_the_extra_chunks() {
        let chunk = |n: &String| n.ends_with(['1', '2', '3']);
        let (plain, _) = specialize(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        let used = globals_used(&plain);
        assert!(used.iter().any(|n| n == "triangles"), "{used:?}");
        assert!(!used.iter().any(chunk), "{used:?}");
        let variant = Variant {
            lists: Lists::Split,
            ..Variant::default()
        };
        let (split, _) = specialize(Methods::Robust, Features::ALL, variant).unwrap();
        let used = globals_used(&split);
        for name in ["triangles3", "normals3", "materials3", "nodes3"] {
            assert!(used.iter().any(|n| n == name), "{name} unused: {used:?}");
        }
    }

    /// A shader with uniform lists reads spheres, triangles and nodes only
    /// from their uniform copies; any other reads only the storage lists.
    #[test]
    fn only_a_uniform_lists_shader_reads_the_uniform_copies() {
        let (plain, _) = specialize(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        let used = globals_used(&plain);
        for name in ["spheres", "triangles", "nodes", "prim_refs"] {
            assert!(used.iter().any(|n| n == name), "{name} unused: {used:?}");
            let copy = format!("{name}_u");
            assert!(!used.contains(&copy), "{copy} used: {used:?}");
        }
        let variant = Variant {
            lists: Lists::Uniform,
            ..Variant::default()
        };
        let (uniform, _) = specialize(Methods::Robust, Features::ALL, variant).unwrap();
        let used = globals_used(&uniform);
        for name in ["spheres", "triangles", "nodes", "prim_refs"] {
            let copy = format!("{name}_u");
            assert!(used.contains(&copy), "{copy} unused: {used:?}");
            // The leaf loop still bounds a reference by the list's length.
            if name != "prim_refs" {
                assert!(!used.iter().any(|n| n == name), "{name} used: {used:?}");
            }
        }
        // Triangles as corners: shading reads the list for the materials.
        let variant = Variant {
            lists: Lists::Uniform,
            corners: true,
            ..Variant::default()
        };
        let (corners, _) = specialize(Methods::Robust, Features::ALL, variant).unwrap();
        let used = globals_used(&corners);
        for name in ["triangles_u", "triangles"] {
            assert!(used.iter().any(|n| n == name), "{name} unused: {used:?}");
        }
    }

    /// A shader with address lists reads the `layout::ADDRESS_LISTS` only
    /// through `device_memory`'s loads; it still takes their bindings'
    /// lengths, to clamp its indices.
    #[test]
    fn an_address_lists_shader_reads_its_lists_only_through_device_loads() {
        let variant = Variant {
            lists: Lists::Address,
            ..Variant::default()
        };
        let (m, _) = specialize(Methods::Robust, Features::ALL, variant).unwrap();
        let indexed = globals_indexed(&m);
        assert!(indexed.iter().any(|n| n == "device_memory"), "{indexed:?}");
        for name in [
            "spheres",
            "triangles",
            "nodes",
            "prim_refs",
            "normals",
            "materials",
        ] {
            assert!(
                !indexed.iter().any(|n| n == name),
                "{name} read: {indexed:?}"
            );
        }
        let (plain, _) = specialize(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        let indexed = globals_indexed(&plain);
        assert!(!indexed.iter().any(|n| n == "device_memory"));
        assert!(indexed.iter().any(|n| n == "nodes"), "{indexed:?}");
    }

    #[test]
    fn every_feature_set_compiles() {
        for bits in 0..64u32 {
            let f = Features {
                spheres: bits & 1 != 0,
                triangles: bits & 2 != 0,
                reflection: bits & 4 != 0,
                area_lights: bits & 8 != 0,
                motion_blur: bits & 16 != 0,
                multisample: bits & 32 != 0,
            };
            for methods in Methods::ALL {
                for lists in Lists::ALL {
                    for (light_skips, corners, leaf_order, one_pass) in [
                        (false, false, false, false),
                        (true, false, false, true),
                        (false, true, false, false),
                        (true, true, true, true),
                    ] {
                        let variant = Variant {
                            lists,
                            light_skips,
                            corners,
                            leaf_order,
                            one_pass,
                        };
                        spirv(methods, f, variant).unwrap_or_else(|e| panic!("{e}"));
                    }
                }
            }
        }
    }
}
