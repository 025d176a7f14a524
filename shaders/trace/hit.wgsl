// shaders/trace/hit.wgsl: the box, sphere and triangle tests, robust and
// naive. CPU twin: src/cpu/trace/hit.rs.

// Entry distance of the ray into the box within [0, t_max], or T_INF if it misses.
fn hit_aabb(ray: Ray, bmin: vec3<f32>, bmax: vec3<f32>, t_max: f32) -> f32 {
    let t0 = (bmin - ray.origin) * ray.inv_dir;
    let t1 = (bmax - ray.origin) * ray.inv_dir;
    let tn = min(t0, t1);
    let tf = max(t0, t1);
    let t_near = max(max(tn.x, tn.y), max(tn.z, 0.0));
    let t_far = min(min(tf.x, tf.y), min(tf.z, t_max)) * BOX_T_SCALE;
    return select(T_INF, t_near, t_near <= t_far);
}

// Both t where the ray's line meets the sphere (unordered), or T_INF twice
// when it misses, or only grazes it: its discriminant is below `band` (see
// graze_band; 0 but for some shadow rays). Ray Tracing Gems ch. 7 (Haines et al.): the discriminant
// from the perpendicular distance to the centre and the stable root pair
// avoid catastrophic cancellation for small or distant spheres.
fn sphere_roots(ray: Ray, s: Sphere, band: f32) -> vec2<f32> {
    let f = ray.origin - s.center;
    let a = dot(ray.dir, ray.dir);
    let b = -dot(f, ray.dir);
    let c = dot(f, f) - s.radius * s.radius;
    let l = f + (b / a) * ray.dir;
    let disc = s.radius * s.radius - dot(l, l);
    if (disc < band) {
        return vec2(T_INF);
    }
    let q = b + sign_nonzero(b) * sqrt(a * disc);
    return vec2(c / q, q / a);
}

// Nearest t in (0, t_max) where the ray meets the sphere, or T_INF.
fn hit_sphere(ray: Ray, s: Sphere, t_max: f32, band: f32) -> f32 {
    if (!ROBUST) {
        return hit_sphere_naive(ray, s, t_max);
    }
    let roots = sphere_roots(ray, s, band);
    let t_lo = min(roots.x, roots.y);
    let t_hi = max(roots.x, roots.y);
    if (t_lo > 0.0 && t_lo < t_max) {
        return t_lo;
    }
    if (t_hi > 0.0 && t_hi < t_max) {
        return t_hi;
    }
    return T_INF;
}

// The textbook quadratic: b^2 - 4ac cancels catastrophically when the sphere
// is small against its distance.
fn hit_sphere_naive(ray: Ray, s: Sphere, t_max: f32) -> f32 {
    let oc = ray.origin - s.center;
    let a = dot(ray.dir, ray.dir);
    let b = 2.0 * dot(oc, ray.dir);
    let c = dot(oc, oc) - s.radius * s.radius;
    let disc = b * b - 4.0 * a * c;
    if (disc < 0.0) {
        return T_INF;
    }
    let root = sqrt(disc);
    let t0 = (-b - root) / (2.0 * a);
    let t1 = (-b + root) / (2.0 * a);
    if (t0 > 0.0 && t0 < t_max) {
        return t0;
    }
    if (t1 > 0.0 && t1 < t_max) {
        return t1;
    }
    return T_INF;
}

// Möller and Trumbore 1997, as most ray tracers of this assignment write it:
// barycentric bounds tested per triangle (shared edges can fall between two
// neighbours) and an absolute determinant epsilon (small triangles vanish).
fn hit_triangle_naive(ray: Ray, tri: Triangle, t_max: f32) -> vec3<f32> {
    let e1 = tri.v[1].xyz - tri.v[0].xyz;
    let e2 = tri.v[2].xyz - tri.v[0].xyz;
    let pv = cross(ray.dir, e2);
    let det = dot(e1, pv);
    if (abs(det) < NAIVE_DET_EPSILON) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let inv_det = 1.0 / det;
    let tv = ray.origin - tri.v[0].xyz;
    let u = dot(tv, pv) * inv_det;
    if (u < 0.0 || u > 1.0) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let qv = cross(tv, e1);
    let v = dot(ray.dir, qv) * inv_det;
    if (v < 0.0 || u + v > 1.0) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let t = dot(e2, qv) * inv_det;
    if (t <= 0.0 || t >= t_max) {
        return vec3(T_INF, 0.0, 0.0);
    }
    return vec3(t, u, v);
}

// Watertight ray/triangle test (Woop, Benthin, Wald 2013). Edges count as
// inside for both neighbours, so a ray through a shared edge or vertex hits
// at least one of them; there is no epsilon on the determinant.
// Returns (t, b1, b2) with t = T_INF for a miss.
fn hit_triangle(ray: Ray, tri: Triangle, t_max: f32) -> vec3<f32> {
    if (!ROBUST) {
        return hit_triangle_naive(ray, tri, t_max);
    }
    let a = tri.v[0].xyz - ray.origin;
    let b = tri.v[1].xyz - ray.origin;
    let c = tri.v[2].xyz - ray.origin;
    let k = ray.k;
    let s = ray.shear;
    let ax = a[k.x] - s.x * a[k.z];
    let ay = a[k.y] - s.y * a[k.z];
    let bx = b[k.x] - s.x * b[k.z];
    let by = b[k.y] - s.y * b[k.z];
    let cx = c[k.x] - s.x * c[k.z];
    let cy = c[k.y] - s.y * c[k.z];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let det = u + v + w;
    if (det == 0.0) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let az = s.z * a[k.z];
    let bz = s.z * b[k.z];
    let cz = s.z * c[k.z];
    let t_scaled = u * az + v * bz + w * cz;
    // t = t_scaled / det must lie in (0, t_max); compare without dividing.
    let positive = (t_scaled > 0.0) && (t_scaled < t_max * det);
    let negative = (t_scaled < 0.0) && (t_scaled > t_max * det);
    let inside = select(negative, positive, det > 0.0);
    if (!inside) {
        return vec3(T_INF, 0.0, 0.0);
    }
    let inv_det = 1.0 / det;
    return vec3(t_scaled * inv_det, v * inv_det, w * inv_det);
}

