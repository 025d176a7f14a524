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

use super::pipeline::Lists;
use crate::info::Features;
use crate::methods::Methods;

/// The shader source, compiled into the binary.
pub const TRACE_WGSL: &str = include_str!("../../shaders/trace.wgsl");
const TRACE_PATH: &str = "shaders/trace.wgsl";

/// The shader failed to compile: a bug in glint, not in the user's input.
#[derive(Debug, Clone, thiserror::Error)]
#[error("building the trace shader ({what}) failed: {message}; this is a bug in glint, please report it")]
pub struct ShaderError {
    pub what: String,
    pub message: String,
}

fn parsed() -> Result<&'static (Module, ModuleInfo), ShaderError> {
    static PARSED: OnceLock<Result<(Module, ModuleInfo), ShaderError>> = OnceLock::new();
    PARSED
        .get_or_init(|| {
            let fail = |message| ShaderError {
                what: "parse".into(),
                message,
            };
            let module = naga::front::wgsl::parse_str(TRACE_WGSL)
                .map_err(|e| fail(e.emit_to_string_with_path(TRACE_WGSL, TRACE_PATH)))?;
            let info = validator()
                .validate(&module)
                .map_err(|e| fail(e.emit_to_string_with_path(TRACE_WGSL, TRACE_PATH)))?;
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
    let words = unfill_local_arrays(&words);
    Ok(if variant.lists == Lists::Address {
        device_loads(&words)
    } else {
        words
    })
}

/// Function-scope arrays the shader writes before it reads any element, so
/// that they need no zero fill (`unfill_local_arrays`); a test holds the
/// shader to this list.
pub const UNFILLED_ARRAYS: [&str; 1] = ["groups"];

const OP_TYPE_ARRAY: u32 = spirv::Op::TypeArray as u32;
const OP_TYPE_POINTER: u32 = spirv::Op::TypePointer as u32;
const OP_CONSTANT_NULL: u32 = spirv::Op::ConstantNull as u32;
const OP_VARIABLE: u32 = spirv::Op::Variable as u32;
const STORAGE_FUNCTION: u32 = spirv::StorageClass::Function as u32;
/// Words before the first instruction of a SPIR-V module.
const HEADER_WORDS: usize = 5;

/// The (opcode, operands) of each instruction after the header.
fn instructions(words: &[u32]) -> impl Iterator<Item = (u32, &[u32])> {
    let mut at = HEADER_WORDS;
    std::iter::from_fn(move || {
        let head = *words.get(at)?;
        let len = ((head >> 16) as usize).max(1);
        let operands = words.get(at + 1..at + len)?;
        at += len;
        Some((head & 0xffff, operands))
    })
}

/// Appends the instruction `op` with its operands (the inverse of
/// `instructions`).
fn push_instruction(out: &mut Vec<u32>, op: u32, operands: &[u32]) {
    out.push(((operands.len() as u32 + 1) << 16) | op);
    out.extend_from_slice(operands);
}

/// Drops the zero fill from every function-scope array variable.
///
/// WGSL zero-fills each function variable, and naga writes that as an
/// `OpConstantNull` initialiser, which a driver must honour each time the
/// function is entered unless it can prove the fill dead. For the traversal
/// stack (`UNFILLED_ARRAYS`, written before read) it cannot, and on lavapipe
/// (Mesa 22.3) the fill was a store per element and lane on every ray,
/// about a fifth of SIGGRAPH's render time. Scalars and structs keep their
/// fill.
pub fn unfill_local_arrays(words: &[u32]) -> Vec<u32> {
    let mut arrays = HashSet::new();
    let mut nulls = HashSet::new();
    let mut array_pointers = HashSet::new();
    for (op, o) in instructions(words) {
        match op {
            OP_TYPE_ARRAY => {
                arrays.insert(o[0]);
            }
            OP_TYPE_POINTER if o[1] == STORAGE_FUNCTION && arrays.contains(&o[2]) => {
                array_pointers.insert(o[0]);
            }
            OP_CONSTANT_NULL => {
                nulls.insert(o[1]);
            }
            _ => {}
        }
    }
    let mut out = words[..HEADER_WORDS.min(words.len())].to_vec();
    for (op, o) in instructions(words) {
        let unfill = op == OP_VARIABLE
            && o.len() == 4
            && o[2] == STORAGE_FUNCTION
            && array_pointers.contains(&o[0])
            && nulls.contains(&o[3]);
        push_instruction(&mut out, op, if unfill { &o[..3] } else { o });
    }
    out
}

/// The binding of `device_memory`, the never-bound array whose reads mark
/// the shader's loads through device addresses (`device_loads`).
pub const DEVICE_MEMORY_BINDING: u32 = 30;

const OP_MEMORY_MODEL: u32 = spirv::Op::MemoryModel as u32;
const OP_CAPABILITY: u32 = spirv::Op::Capability as u32;
const OP_DECORATE: u32 = spirv::Op::Decorate as u32;
const OP_TYPE_INT: u32 = spirv::Op::TypeInt as u32;
const OP_TYPE_VECTOR: u32 = spirv::Op::TypeVector as u32;
const OP_FUNCTION: u32 = spirv::Op::Function as u32;
const OP_FUNCTION_END: u32 = spirv::Op::FunctionEnd as u32;
const OP_ACCESS_CHAIN: u32 = spirv::Op::AccessChain as u32;

/// A string operand: UTF-8, nul-terminated, padded to whole words.
fn string_words(s: &str) -> Vec<u32> {
    let mut bytes = s.as_bytes().to_vec();
    bytes.push(0);
    bytes.resize(bytes.len().div_ceil(4) * 4, 0);
    bytes
        .chunks(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Turns each function that reads `device_memory` (the shader's
/// `device_load4` and `device_load1`) into a load of element `i` of an
/// array at a device address: its parameters are the address as a
/// `vec2<u32>` of (low, high) words and `i`. The address is bitcast to a
/// 64-bit integer and converted to a PhysicalStorageBuffer pointer to a
/// block holding a runtime array of the function's result type (as
/// glslang writes a `buffer_reference` block); element `i` is loaded with
/// that type's alignment. The module gains the capabilities
/// (PhysicalStorageBuffer addresses, Int64), the extension and the
/// addressing model this needs, and naga's unused access chains to
/// `device_memory` in the callers go, so it needs no binding. WGSL has no
/// pointers into device memory, hence this pass (see "Address lists" in
/// shaders/trace.wgsl).
pub fn device_loads(words: &[u32]) -> Vec<u32> {
    let list: Vec<(u32, &[u32])> = instructions(words).collect();
    let mut marker = None;
    let mut u32_type = None;
    let mut vectors = Vec::new();
    for &(op, o) in &list {
        match op {
            OP_DECORATE
                if o.len() == 3
                    && o[1] == spirv::Decoration::Binding as u32
                    && o[2] == DEVICE_MEMORY_BINDING =>
            {
                marker = Some(o[0]);
            }
            OP_TYPE_INT if o[1] == 32 && o[2] == 0 => u32_type = Some(o[0]),
            OP_TYPE_VECTOR => vectors.push((o[0], o[1], o[2])),
            _ => {}
        }
    }
    let (Some(marker), Some(u32_type)) = (marker, u32_type) else {
        return words.to_vec();
    };
    // naga opens each function with an access chain to every global its
    // call tree uses, so the marker's chains are of two kinds: one that a
    // further access chain indexes (a read: that function is a load to
    // rewrite), and unused ones in its callers (dropped).
    let chains: HashSet<u32> = list
        .iter()
        .filter(|(op, o)| *op == OP_ACCESS_CHAIN && o[2] == marker)
        .map(|(_, o)| o[1])
        .collect();
    // The load functions: where each starts, its result type.
    let mut loads = Vec::new();
    let mut start = None;
    for (i, &(op, o)) in list.iter().enumerate() {
        match op {
            OP_FUNCTION => start = Some((i, o[0])),
            OP_ACCESS_CHAIN if chains.contains(&o[2]) => {
                if let Some(f) = start.take() {
                    loads.push(f);
                }
            }
            _ => {}
        }
    }
    let mut bound = words[3];
    let mut fresh = || {
        bound += 1;
        bound - 1
    };
    let u64_type = fresh();
    let zero = fresh();
    // Per result type of the loads (a u32 or a vector of them), the types
    // of an array of it in device memory, as glslang writes a
    // buffer_reference block: a Block struct holding a runtime array.
    let mut arrays: Vec<DeviceArray> = Vec::new();
    for &(_, ty) in &loads {
        if arrays.iter().all(|p| p.element != ty) {
            let components = vectors
                .iter()
                .find(|v| v.0 == ty && v.1 == u32_type)
                .map_or(1, |v| v.2);
            arrays.push(DeviceArray {
                element: ty,
                bytes: 4 * components,
                runtime_array: fresh(),
                block: fresh(),
                block_pointer: fresh(),
                element_pointer: fresh(),
            });
        }
    }
    let psb = spirv::StorageClass::PhysicalStorageBuffer as u32;
    let mut out = words[..HEADER_WORDS].to_vec();
    let emit = |out: &mut Vec<u32>, op: spirv::Op, operands: &[u32]| {
        push_instruction(out, op as u32, operands);
    };
    let mut capabilities = false;
    let mut extension = false;
    let mut decorations = false;
    let mut types = false;
    let mut at = 0;
    while at < list.len() {
        let (op, o) = list[at];
        if op != OP_CAPABILITY && !extension {
            // After the capabilities, before everything else.
            extension = true;
            emit(
                &mut out,
                spirv::Op::Extension,
                &string_words("SPV_KHR_physical_storage_buffer"),
            );
        }
        if op == OP_MEMORY_MODEL {
            emit(
                &mut out,
                spirv::Op::MemoryModel,
                &[spirv::AddressingModel::PhysicalStorageBuffer64 as u32, o[1]],
            );
            at += 1;
            continue;
        }
        if op == OP_DECORATE && !decorations {
            decorations = true;
            for a in &arrays {
                let stride = spirv::Decoration::ArrayStride as u32;
                emit(
                    &mut out,
                    spirv::Op::Decorate,
                    &[a.runtime_array, stride, a.bytes],
                );
                let block = spirv::Decoration::Block as u32;
                emit(&mut out, spirv::Op::Decorate, &[a.block, block]);
                let offset = spirv::Decoration::Offset as u32;
                emit(
                    &mut out,
                    spirv::Op::MemberDecorate,
                    &[a.block, 0, offset, 0],
                );
                let readonly = spirv::Decoration::NonWritable as u32;
                emit(&mut out, spirv::Op::MemberDecorate, &[a.block, 0, readonly]);
            }
        }
        if op == OP_FUNCTION && !types {
            types = true;
            emit(&mut out, spirv::Op::TypeInt, &[u64_type, 64, 0]);
            emit(&mut out, spirv::Op::Constant, &[u32_type, zero, 0]);
            for a in &arrays {
                emit(
                    &mut out,
                    spirv::Op::TypeRuntimeArray,
                    &[a.runtime_array, a.element],
                );
                emit(&mut out, spirv::Op::TypeStruct, &[a.block, a.runtime_array]);
                emit(
                    &mut out,
                    spirv::Op::TypePointer,
                    &[a.block_pointer, psb, a.block],
                );
                emit(
                    &mut out,
                    spirv::Op::TypePointer,
                    &[a.element_pointer, psb, a.element],
                );
            }
        }
        if let Some(&(_, ty)) = loads.iter().find(|l| l.0 == at) {
            let a = arrays.iter().find(|a| a.element == ty).expect("listed");
            let (_, base) = list[at + 1];
            let (_, index) = list[at + 2];
            let [label, address, block, element, value] =
                [fresh(), fresh(), fresh(), fresh(), fresh()];
            emit(&mut out, spirv::Op::Function, o);
            emit(&mut out, spirv::Op::FunctionParameter, base);
            emit(&mut out, spirv::Op::FunctionParameter, index);
            emit(&mut out, spirv::Op::Label, &[label]);
            emit(&mut out, spirv::Op::Bitcast, &[u64_type, address, base[1]]);
            emit(
                &mut out,
                spirv::Op::ConvertUToPtr,
                &[a.block_pointer, block, address],
            );
            emit(
                &mut out,
                spirv::Op::AccessChain,
                &[a.element_pointer, element, block, zero, index[1]],
            );
            let aligned = spirv::MemoryAccess::ALIGNED.bits();
            emit(
                &mut out,
                spirv::Op::Load,
                &[ty, value, element, aligned, a.bytes],
            );
            emit(&mut out, spirv::Op::ReturnValue, &[value]);
            emit(&mut out, spirv::Op::FunctionEnd, &[]);
            while list[at].0 != OP_FUNCTION_END {
                at += 1;
            }
            at += 1;
            continue;
        }
        if op == OP_ACCESS_CHAIN && o[2] == marker {
            at += 1;
            continue;
        }
        push_instruction(&mut out, op, o);
        if op == OP_CAPABILITY && !capabilities {
            capabilities = true;
            for c in [
                spirv::Capability::Int64,
                spirv::Capability::PhysicalStorageBufferAddresses,
            ] {
                emit(&mut out, spirv::Op::Capability, &[c as u32]);
            }
        }
        at += 1;
    }
    out[3] = bound;
    out
}

/// The types `device_loads` adds for reading an array of `element` (of
/// `bytes`) through a device address.
struct DeviceArray {
    element: u32,
    bytes: u32,
    runtime_array: u32,
    block: u32,
    block_pointer: u32,
    element_pointer: u32,
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

    /// The ids of the instructions with opcode `op` (result id at `at`).
    fn results(words: &[u32], op: spirv::Op, at: usize) -> Vec<u32> {
        instructions(words)
            .filter(|&(o, _)| o == op as u32)
            .map(|(_, o)| o[at])
            .collect()
    }

    #[test]
    fn device_loads_replace_every_read_of_the_marker() {
        let variant = Variant {
            lists: Lists::Address,
            ..Variant::default()
        };
        let (module, info) = specialize(Methods::Robust, Features::ALL, variant).unwrap();
        let raw = spv::write_vec(&module, &info, &spv::Options::default(), None).unwrap();
        let marker = instructions(&raw)
            .find(|&(op, o)| {
                op == OP_DECORATE
                    && o[1] == spirv::Decoration::Binding as u32
                    && o[2] == DEVICE_MEMORY_BINDING
            })
            .map(|(_, o)| o[0])
            .expect("the marker is declared");
        let reads = |words: &[u32]| {
            instructions(words)
                .filter(|&(op, o)| op == OP_ACCESS_CHAIN && o[2] == marker)
                .count()
        };
        assert!(
            reads(&raw) > 2,
            "naga reads the marker in loads and callers"
        );
        let words = device_loads(&raw);
        assert_eq!(reads(&words), 0);
        // One load per function that read it (device_load4, device_load1),
        // each through a pointer made from its 64-bit address.
        assert_eq!(results(&words, spirv::Op::ConvertUToPtr, 1).len(), 2);
        let loads: Vec<&[u32]> = instructions(&words)
            .filter(|&(op, o)| op == spirv::Op::Load as u32 && o.len() == 5)
            .map(|(_, o)| o)
            .collect();
        let mut aligned: Vec<u32> = loads
            .iter()
            .filter(|o| o[3] == spirv::MemoryAccess::ALIGNED.bits())
            .map(|o| o[4])
            .collect();
        aligned.sort();
        assert_eq!(aligned, [4, 16]);
        let capabilities = results(&words, spirv::Op::Capability, 0);
        for c in [
            spirv::Capability::Int64,
            spirv::Capability::PhysicalStorageBufferAddresses,
        ] {
            assert!(capabilities.contains(&(c as u32)), "{c:?}");
        }
        assert_eq!(
            results(&words, spirv::Op::MemoryModel, 0),
            [spirv::AddressingModel::PhysicalStorageBuffer64 as u32]
        );
        // What the shipped variants get: only the address one changes.
        let shipped = spirv(Methods::Robust, Features::ALL, variant).unwrap();
        assert_eq!(reads(&shipped), 0);
        let plain = spirv(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        assert!(results(&plain, spirv::Op::ConvertUToPtr, 1).is_empty());
        assert_eq!(
            results(&plain, spirv::Op::MemoryModel, 0),
            [spirv::AddressingModel::Logical as u32]
        );
    }

    /// Function-scope variables of array type, by name, over every function
    /// and entry point.
    fn local_arrays(m: &Module) -> Vec<String> {
        let functions = m.functions.iter().map(|(_, f)| f);
        let mut names: Vec<String> = functions
            .chain(m.entry_points.iter().map(|ep| &ep.function))
            .flat_map(|f| f.local_variables.iter())
            .filter(|(_, v)| matches!(m.types[v.ty].inner, naga::TypeInner::Array { .. }))
            .map(|(_, v)| v.name.clone().unwrap_or_default())
            .collect();
        names.sort();
        names.dedup();
        names
    }

    #[test]
    fn only_arrays_written_before_read_go_unfilled() {
        // A new function-scope array must be shown to be written before it
        // is read, and listed, or it would read leftovers where WGSL
        // promises zeros.
        let (m, _) = parsed().unwrap();
        assert_eq!(local_arrays(m), UNFILLED_ARRAYS.to_vec());
    }

    /// (Function-scope variables with an initialiser whose type is an
    /// array, those whose type is not, all instructions.)
    fn fills(words: &[u32]) -> (usize, usize, usize) {
        let arrays: HashSet<u32> = instructions(words)
            .filter(|&(op, _)| op == OP_TYPE_ARRAY)
            .map(|(_, o)| o[0])
            .collect();
        let pointee: std::collections::HashMap<u32, u32> = instructions(words)
            .filter(|&(op, _)| op == OP_TYPE_POINTER)
            .map(|(_, o)| (o[0], o[2]))
            .collect();
        let filled = instructions(words)
            .filter(|&(op, o)| op == OP_VARIABLE && o[2] == STORAGE_FUNCTION && o.len() == 4);
        let (a, other): (Vec<_>, Vec<_>) =
            filled.partition(|(_, o)| arrays.contains(&pointee[&o[0]]));
        (a.len(), other.len(), instructions(words).count())
    }

    #[test]
    fn unfilling_drops_the_array_fills_and_nothing_else() {
        let (module, info) =
            specialize(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        let raw = spv::write_vec(&module, &info, &spv::Options::default(), None).unwrap();
        let (arrays, other, count) = fills(&raw);
        assert!(arrays >= 1 && other >= 1, "{arrays} {other}");
        let unfilled = unfill_local_arrays(&raw);
        assert_eq!(fills(&unfilled), (0, other, count));
        assert_eq!(unfilled.len(), raw.len() - arrays);
        assert_eq!(unfilled[..HEADER_WORDS], raw[..HEADER_WORDS]);
        let shipped = spirv(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        assert_eq!(fills(&shipped).0, 0);
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
