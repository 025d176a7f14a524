// shaders/trace/traverse.wgsl: the wide tree's traversal for the closest
// hit or any blocker, with light skips and the grazing band. CPU twin:
// src/cpu/trace/traverse.rs.

// The run of `skips` (first, count) for the shadow ray being traced, set by
// point_term (the only caller of occluder); read only by any-hit traversal.
var<private> skip_range: vec2<u32>;
// The grazing band's height for that shadow ray (in_plane_graze), set and
// read alike.
var<private> graze_h: f32;

// The least discriminant r^2 - |l|^2 at which a shadow ray whose line may
// lie up to h off its true one still meets a sphere of radius r (h = 0:
// any). Moving a line by h changes |l|^2 by at most 2 r h + h^2, so within
// the band it may only graze the sphere; the sphere's own rounding adds
// ON_SURFACE r to h.
fn graze_band(h: f32, r: f32) -> f32 {
    if (h <= 0.0) {
        return 0.0;
    }
    let hr = h + ON_SURFACE * r;
    return hr * (2.0 * r + hr);
}

// For a shadow ray towards a point light on a surface: when the light lies
// in the plane of the surface the ray leaves (within the ray's own lift off
// it and the light's rounding), the height of the band within which the
// ray's true line runs inside that plane, else 0. Such a line can only
// touch a sphere resting on the plane, so lifted by the origin offset it
// must not be blocked by clipping one.
fn in_plane_graze(sp: SurfacePoint, origin: vec3<f32>, light_pos: vec3<f32>) -> f32 {
    let to_light = light_pos - sp.p;
    let t = abs(light_pos);
    let h = 2.0 * length(origin - sp.p) + ON_SURFACE * (max(max(t.x, t.y), t.z) + length(to_light));
    return select(0.0, 2.0 * h, abs(dot(sp.ng, to_light)) <= h);
}

fn skipped(prim: u32) -> bool {
    var found = false;
    var k = 0u;
    for (; k < skip_range.y; k++) {
        work += 1u;
        if (skips[skip_range.x + k] == prim) {
            found = true;
        }
    }
    if (k < skip_range.y) {
        cut = true;
    }
    return found;
}

// For a sphere through the light a shadow ray ends at: the crossing that is
// not the light's own, when it lies in (0, 1 - TANGENT_BAND), else T_INF.
fn hit_sphere_through_end(ray: Ray, s: Sphere) -> f32 {
    let roots = sphere_roots(ray, s, graze_band(graze_h, s.radius));
    // The root nearer 1 is the light's own (a miss gives T_INF either way).
    let other = select(roots.y, roots.x, abs(roots.x - 1.0) > abs(roots.y - 1.0));
    if (other > 0.0 && other < 1.0 - TANGENT_BAND) {
        return other;
    }
    return T_INF;
}

// Tests the primitive `prim` (a reference without its LEAF_END bit); true
// when `any_hit` and it blocks, so the traversal can stop.
fn hit_prim(ray: Ray, prim: u32, best: ptr<function, Hit>, any_hit: bool) -> bool {
    let index = prim & ~SPHERE_BIT;
    if (LIGHT_SKIPS) {
        if (any_hit && skipped(prim)) {
            // A surface through the light: triangles never block it, a
            // sphere only with its other crossing.
            if ((prim & SPHERE_BIT) != 0u) {
                let t = hit_sphere_through_end(ray, sphere_at(index, ray.time));
                if (t < (*best).t) {
                    *best = Hit(t, prim, 0.0, 0.0);
                    return true;
                }
            }
            return false;
        }
    }
    if ((prim & SPHERE_BIT) != 0u) {
        if (SPHERES) {
            let s = sphere_at(index, ray.time);
            var band = 0.0;
            if (LIGHT_SKIPS) {
                band = select(0.0, graze_band(graze_h, s.radius), any_hit);
            }
            let t = hit_sphere(ray, s, (*best).t, band);
            if (t < (*best).t) {
                *best = Hit(t, prim, 0.0, 0.0);
                return any_hit;
            }
        }
    } else {
        if (TRIANGLES) {
            let h = hit_triangle(ray, corners_at(index, ray.time), (*best).t);
            if (h.x < (*best).t) {
                *best = Hit(h.x, prim, h.y, h.z);
                return any_hit;
            }
        }
    }
    return false;
}

// The four bytes of w, lowest first.
fn unpack_bytes(w: u32) -> vec4<f32> {
    return vec4<f32>((vec4(w) >> vec4(0u, 8u, 16u, 24u)) & vec4(0xffu));
}

// Entry distances of the ray into a node's four child boxes within
// [0, t_max]: each box decoded (it holds the binary tree's f32 box; see
// GpuWideNode), then hit_aabb's arithmetic lane by lane; T_INF where it
// misses and in unused lanes (which a NaN ray would otherwise pass).
fn hit_boxes(ray: Ray, node: WideNode, t_max: f32) -> vec4<f32> {
    let o = ray.origin;
    let d = ray.inv_dir;
    let e = bitcast<u32>(node.origin.w);
    let s = vec3(bitcast<f32>((e & 0xffu) << 23u), bitcast<f32>(((e >> 8u) & 0xffu) << 23u),
        bitcast<f32>(((e >> 16u) & 0xffu) << 23u));
    let lo_x = node.origin.x + unpack_bytes(node.lo_hi.x) * s.x;
    let lo_y = node.origin.y + unpack_bytes(node.lo_hi.y) * s.y;
    let lo_z = node.origin.z + unpack_bytes(node.lo_hi.z) * s.z;
    let hi_x = node.origin.x + unpack_bytes(node.lo_hi.w) * s.x;
    let hi_y = node.origin.y + unpack_bytes(node.hi_yz.x) * s.y;
    let hi_z = node.origin.z + unpack_bytes(node.hi_yz.y) * s.z;
    let x0 = (lo_x - o.x) * d.x;
    let x1 = (hi_x - o.x) * d.x;
    let y0 = (lo_y - o.y) * d.y;
    let y1 = (hi_y - o.y) * d.y;
    let z0 = (lo_z - o.z) * d.z;
    let z1 = (hi_z - o.z) * d.z;
    let t_near = max(max(min(x0, x1), min(y0, y1)), max(min(z0, z1), vec4(0.0)));
    let t_far = min(min(max(x0, x1), max(y0, y1)), min(max(z0, z1), vec4(t_max))) * BOX_T_SCALE;
    let hit = (t_near <= t_far) & (node.child != vec4(WIDE_EMPTY));
    return select(vec4(T_INF), t_near, hit);
}

// A child lane of a node: its entry distance (T_INF: missed), its word
// (WideNode.child) and its lane.
struct Child {
    t: f32,
    word: u32,
    lane: u32,
}

// Puts a and b in visiting order: nearer first, the later lane first at
// equal t (the CPU reference's order).
fn order(a: ptr<function, Child>, b: ptr<function, Child>) {
    let x = *a;
    let y = *b;
    if (y.t < x.t || (y.t == x.t && y.lane > x.lane)) {
        *a = y;
        *b = x;
    }
}

// A leaf lane's first reference slot (its word less WIDE_LEAF, and with
// LEAF_ORDER less its count: layout::LEAF_COUNT_SHIFT).
fn leaf_first(word: u32) -> u32 {
    if (LEAF_ORDER) {
        return word & ((1u << LEAF_COUNT_SHIFT) - 1u);
    }
    return word & ~WIDE_LEAF;
}

// With LEAF_ORDER: the slot after a leaf lane's last.
fn leaf_end(word: u32) -> u32 {
    return leaf_first(word) + ((word >> LEAF_COUNT_SHIFT) & LEAF_COUNT_MASK) + 1u;
}

// Appends c's word to out[k] when c was hit and is a leaf (kind WIDE_LEAF)
// or a node (kind 0).
fn append_hit(out: ptr<function, vec4<u32>>, k: ptr<function, u32>, c: Child, kind: u32) {
    let take = c.t < T_INF && (c.word & WIDE_LEAF) == kind;
    *out = select(*out, vec4(c.word), vec4(take) & (vec4(*k) == vec4(0u, 1u, 2u, 3u)));
    *k += u32(take);
}

// Walks the four-wide BVH. Closest hit in (0, t_max), or with `any_hit` the
// first hit found (shadow rays stop at the first blocker).
//
// A node's hit children are taken in the CPU reference's order
// (src/cpu/trace/hit.rs: traverse_from): its leaves at once, then its inner
// nodes from the stack, each nearest first and, at equal entry distance,
// the later lane first. The distances are to the decoded boxes, a little larger than the
// CPU's, so the order may differ from the CPU's where two entries are
// close; which of two hits at exactly the same t is kept depends only on
// the tree, never on the run.
fn traverse(ray: Ray, t_max: f32, any_hit: bool) -> Hit {
    var best = Hit(t_max, NO_HIT, 0.0, 0.0);
    if (frame.node_count == 0u) {
        return best;
    }
    // Nodes still to visit, in groups of up to three, one group per node
    // that left any: `top` holds the newest (indices in xyz, how many in
    // w), `groups` the older ones. A node stores at most one group, and the
    // tree is at most BVH_MAX_DEPTH deep, so TRAVERSAL_STACK groups cannot
    // overflow. Groups rather than single entries: one vec4 store a node
    // instead of up to three scattered ones.
    var groups: array<vec4<u32>, TRAVERSAL_STACK>;
    var gsp = 0u;
    var top = vec4(0u);
    var entry = 0u;
    var steps = 0u;
    var finished = false;
    loop {
        if (steps >= MAX_TRAVERSAL_STEPS) {
            break;
        }
        steps += 1u;
        work += 1u;
        let node = load_node(entry);
        let t4 = hit_boxes(ray, node, best.t);
        var a = Child(t4.x, node.child.x, 0u);
        var b = Child(t4.y, node.child.y, 1u);
        var c = Child(t4.z, node.child.z, 2u);
        var d = Child(t4.w, node.child.w, 3u);
        // Five compare-exchanges order any four.
        order(&a, &b);
        order(&c, &d);
        order(&a, &c);
        order(&b, &d);
        order(&b, &c);
        // The hit leaves are tested here, nearest first (measured a little
        // faster on lavapipe than stacking them as entries).
        var leaves = vec4(0u);
        var kl = 0u;
        append_hit(&leaves, &kl, a, WIDE_LEAF);
        append_hit(&leaves, &kl, b, WIDE_LEAF);
        append_hit(&leaves, &kl, c, WIDE_LEAF);
        append_hit(&leaves, &kl, d, WIDE_LEAF);
        // One loop over all their primitives, leaf after leaf (each run ends
        // at its LEAF_END): a lane steps through its own run, instead of
        // every lane waiting out the most leaves and then the longest leaf
        // in two nested loops (4-10% faster on Mesa 22.3, whose loops run
        // their body once even when no lane enters; level on Mesa 25).
        var li = 0u;
        var r = leaf_first(leaves.x);
        var end = leaf_end(leaves.x);
        for (; li < kl && r < arrayLength(&prim_refs);) {
            work += 1u;
            var prim: u32;
            var last: bool;
            if (LEAF_ORDER) {
                // Slot r is triangle r, and the leaf's word says where it
                // ends: no load stands between one triangle and the next.
                prim = r;
                last = r + 1u == end;
            } else {
                var word: u32;
                if (UNIFORM_LISTS) {
                    word = prim_refs_u[r >> 2u][r & 3u];
                } else {
                    if (ADDRESSES) {
                        // Unclamped: the loop's condition bounds r by the
                        // binding's length.
                        word = device_load1(list_address(3u), r);
                    } else {
                        word = prim_refs[r];
                    }
                }
                prim = word & ~LEAF_END;
                last = (word & LEAF_END) != 0u;
            }
            if (hit_prim(ray, prim, &best, any_hit)) {
                return best;
            }
            if (last) {
                li += 1u;
                let next = leaves[min(li, 3u)];
                r = leaf_first(next);
                end = leaf_end(next);
            } else {
                r += 1u;
            }
        }
        if (li < kl) {
            cut = true;
        }
        // The hit inner nodes, farthest first: the nearest is visited next,
        // the rest wait as a group.
        var nodes = vec4(0u);
        var k = 0u;
        append_hit(&nodes, &k, d, 0u);
        append_hit(&nodes, &k, c, 0u);
        append_hit(&nodes, &k, b, 0u);
        append_hit(&nodes, &k, a, 0u);
        if (k > 0u) {
            entry = nodes[k - 1u];
            if (k > 1u) {
                if (top.w > 0u) {
                    groups[gsp] = top;
                    gsp += 1u;
                }
                top = vec4(nodes.xyz, k - 1u);
            }
            continue;
        }
        if (top.w == 0u) {
            if (gsp == 0u) {
                finished = true;
                break;
            }
            gsp -= 1u;
            top = groups[gsp];
        }
        top.w -= 1u;
        entry = top[top.w];
    }
    if (!finished) {
        cut = true;
    }
    return best;
}

fn trace_closest(ray: Ray) -> Hit {
    return traverse(ray, T_INF, false);
}

// The first blocker found strictly between the ray origin (t = 0) and the
// light (t = 1; the direction is unnormalized and ends at the light), or a
// Hit with prim NO_HIT.
fn occluder(ray: Ray) -> Hit {
    return traverse(ray, 1.0, true);
}

