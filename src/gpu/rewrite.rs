//! Rewrites of naga's SPIR-V words that naga cannot be asked for: arrays
//! the shader writes before it reads them lose their zero fill
//! (`unfill_local_arrays`), and the address-lists shader reads its lists
//! through device addresses (`device_loads`).

use std::collections::HashSet;

/// Function-scope arrays the shader writes before it reads any element, so
/// that they need no zero fill (`unfill_local_arrays`); a test holds the
/// shader to this list.
#[cfg(test)]
const UNFILLED_ARRAYS: [&str; 1] = ["groups"];

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
/// shaders/trace/layout.wgsl).
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
    let loads = load_functions(&list, &chains);
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
    let mut out = words[..HEADER_WORDS].to_vec();
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
                a.decorate(&mut out);
            }
        }
        if op == OP_FUNCTION && !types {
            types = true;
            emit(&mut out, spirv::Op::TypeInt, &[u64_type, 64, 0]);
            emit(&mut out, spirv::Op::Constant, &[u32_type, zero, 0]);
            for a in &arrays {
                a.declare(&mut out);
            }
        }
        if let Some(&(_, ty)) = loads.iter().find(|l| l.0 == at) {
            let a = arrays.iter().find(|a| a.element == ty).expect("listed");
            let ids = [fresh(), fresh(), fresh(), fresh(), fresh()];
            let (_, base) = list[at + 1];
            let (_, index) = list[at + 2];
            a.load_function(&mut out, [o, base, index], ids, [u64_type, zero]);
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

/// The load functions of `list`: where each starts, and its result type;
/// a load function is one whose first access chain indexes one of `chains`.
fn load_functions(list: &[(u32, &[u32])], chains: &HashSet<u32>) -> Vec<(usize, u32)> {
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
    loads
}

fn emit(out: &mut Vec<u32>, op: spirv::Op, operands: &[u32]) {
    push_instruction(out, op as u32, operands);
}

impl DeviceArray {
    /// Its stride, and its block's layout and read-only member.
    fn decorate(&self, out: &mut Vec<u32>) {
        let stride = spirv::Decoration::ArrayStride as u32;
        emit(
            out,
            spirv::Op::Decorate,
            &[self.runtime_array, stride, self.bytes],
        );
        let block = spirv::Decoration::Block as u32;
        emit(out, spirv::Op::Decorate, &[self.block, block]);
        let offset = spirv::Decoration::Offset as u32;
        emit(out, spirv::Op::MemberDecorate, &[self.block, 0, offset, 0]);
        let readonly = spirv::Decoration::NonWritable as u32;
        emit(out, spirv::Op::MemberDecorate, &[self.block, 0, readonly]);
    }

    /// Its types: the runtime array, its block, and pointers to both in
    /// physical storage.
    fn declare(&self, out: &mut Vec<u32>) {
        let psb = spirv::StorageClass::PhysicalStorageBuffer as u32;
        emit(
            out,
            spirv::Op::TypeRuntimeArray,
            &[self.runtime_array, self.element],
        );
        emit(
            out,
            spirv::Op::TypeStruct,
            &[self.block, self.runtime_array],
        );
        emit(
            out,
            spirv::Op::TypePointer,
            &[self.block_pointer, psb, self.block],
        );
        emit(
            out,
            spirv::Op::TypePointer,
            &[self.element_pointer, psb, self.element],
        );
    }

    /// A load function's new body: the function and its two parameters as
    /// they were (`[function, base, index]` operands), then element
    /// `index` read from the address `base`. `ids`: fresh ids for the
    /// label, address, block, element and value; `types`: the u64 type
    /// and the constant 0.
    fn load_function(
        &self,
        out: &mut Vec<u32>,
        given: [&[u32]; 3],
        ids: [u32; 5],
        types: [u32; 2],
    ) {
        let [function, base, index] = given;
        let [label, address, block, element, value] = ids;
        let [u64_type, zero] = types;
        emit(out, spirv::Op::Function, function);
        emit(out, spirv::Op::FunctionParameter, base);
        emit(out, spirv::Op::FunctionParameter, index);
        emit(out, spirv::Op::Label, &[label]);
        emit(out, spirv::Op::Bitcast, &[u64_type, address, base[1]]);
        emit(
            out,
            spirv::Op::ConvertUToPtr,
            &[self.block_pointer, block, address],
        );
        emit(
            out,
            spirv::Op::AccessChain,
            &[self.element_pointer, element, block, zero, index[1]],
        );
        let aligned = spirv::MemoryAccess::ALIGNED.bits();
        emit(
            out,
            spirv::Op::Load,
            &[self.element, value, element, aligned, self.bytes],
        );
        emit(out, spirv::Op::ReturnValue, &[value]);
        emit(out, spirv::Op::FunctionEnd, &[]);
    }
}

/// Floating-point arithmetic whose result a driver may fuse into a
/// multiply-add unless told not to.
const FLOAT_ARITHMETIC: [spirv::Op; 8] = [
    spirv::Op::FAdd,
    spirv::Op::FSub,
    spirv::Op::FMul,
    spirv::Op::FDiv,
    spirv::Op::FNegate,
    spirv::Op::VectorTimesScalar,
    spirv::Op::Dot,
    spirv::Op::MatrixTimesVector,
];

/// Every floating-point operation decorated `NoContraction`, so that no
/// driver fuses a multiply and an add into one rounding. The robust
/// intersection tests are watertight only in the arithmetic they were
/// written in (the shared edge's function evaluated the same way on both
/// sides), and the CPU f32 twin follows it operation for operation.
/// Measured on NVIDIA's 580 driver (H200), which contracts where SPIR-V
/// lets it: `vertex_rays` cracked (pixel rays through shared vertices
/// found no triangle) without this; lavapipe never contracts, so it
/// changes no bit there.
pub fn no_contraction(words: &[u32]) -> Vec<u32> {
    if words.len() < HEADER_WORDS {
        return words.to_vec();
    }
    let float_ops: Vec<u32> = FLOAT_ARITHMETIC.iter().map(|&o| o as u32).collect();
    // Result ids: word 2 of these instructions (result type, result id).
    let results: Vec<u32> = instructions(words)
        .filter(|(op, operands)| float_ops.contains(op) && operands.len() >= 2)
        .map(|(_, operands)| operands[1])
        .collect();
    let first_type = instructions(words)
        .position(|(op, _)| (OP_TYPE_VOID..=OP_TYPE_FORWARD_POINTER).contains(&op));
    let mut out = words[..HEADER_WORDS].to_vec();
    for (k, (op, operands)) in instructions(words).enumerate() {
        if Some(k) == first_type {
            for &id in &results {
                push_instruction(&mut out, OP_DECORATE, &[id, DECORATION_NO_CONTRACTION]);
            }
        }
        push_instruction(&mut out, op, operands);
    }
    out
}

const OP_TYPE_VOID: u32 = spirv::Op::TypeVoid as u32;
const OP_TYPE_FORWARD_POINTER: u32 = spirv::Op::TypeForwardPointer as u32;
const DECORATION_NO_CONTRACTION: u32 = spirv::Decoration::NoContraction as u32;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::Features;
    use crate::gpu::bindings::Lists;
    use crate::gpu::shader::{parsed, specialize, spirv as shader_words, Variant};
    use crate::methods::Methods;
    use naga::back::spv;
    use naga::Module;

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
        let shipped = shader_words(Methods::Robust, Features::ALL, variant).unwrap();
        assert_eq!(reads(&shipped), 0);
        let plain = shader_words(Methods::Robust, Features::ALL, Variant::default()).unwrap();
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
        let shipped = shader_words(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        assert_eq!(fills(&shipped).0, 0);
    }

    /// Every float operation's result carries `NoContraction`, the
    /// decorations sit before the first type, and nothing else changes.
    #[test]
    fn every_float_operation_is_kept_from_contraction() {
        let (module, info) =
            specialize(Methods::Robust, Features::ALL, Variant::default()).unwrap();
        let raw = spv::write_vec(&module, &info, &spv::Options::default(), None).unwrap();
        let kept = no_contraction(&raw);
        let decorated: HashSet<u32> = instructions(&kept)
            .filter(|&(op, o)| op == OP_DECORATE && o.get(1) == Some(&DECORATION_NO_CONTRACTION))
            .map(|(_, o)| o[0])
            .collect();
        let float_ops: Vec<u32> = FLOAT_ARITHMETIC.iter().map(|&o| o as u32).collect();
        let results: HashSet<u32> = instructions(&raw)
            .filter(|(op, _)| float_ops.contains(op))
            .map(|(_, o)| o[1])
            .collect();
        assert!(results.len() > 100, "{} float operations", results.len());
        assert_eq!(decorated, results);
        let others = |w: &[u32]| -> Vec<(u32, Vec<u32>)> {
            instructions(w)
                .filter(|&(op, o)| {
                    !(op == OP_DECORATE && o.get(1) == Some(&DECORATION_NO_CONTRACTION))
                })
                .map(|(op, o)| (op, o.to_vec()))
                .collect()
        };
        assert_eq!(others(&kept), others(&raw));
        let first_type = instructions(&kept)
            .position(|(op, _)| (OP_TYPE_VOID..=OP_TYPE_FORWARD_POINTER).contains(&op))
            .unwrap();
        let last_decoration = instructions(&kept)
            .enumerate()
            .filter(|(_, (op, _))| *op == OP_DECORATE)
            .map(|(k, _)| k)
            .max()
            .unwrap();
        assert!(last_decoration < first_type);
    }
}
