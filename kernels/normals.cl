// Area-weighted vertex normals from deformed positions. OpenCL C 1.2,
// self-contained. CPU reference: lib/src/core/vertex_normals.cpp.
//
// Two launches: triangle_normals takes each triangle's cross product once,
// then vertex_normals gathers them per vertex over its incident triangles
// (compressed rows built once on the host, no atomics) in adjacency order
// and normalizes; a vanishing or overflowing sum takes the fallback normal
// (the skinned normal). A vertex has about six triangles, so one cross
// product per triangle instead of one per corner reads a third of the
// positions and does a third of the products (docs/performance.md).

// Triangle t's (b - a) x (c - a), corners in the triangle's order
// (triangles: #F by 3 vertex indices, row-major), unnormalized: its length
// is twice the area, which weights the vertex sums.
__kernel void triangle_normals(const uint triangle_count,
                               __global const float* positions,
                               __global const int* triangles,
                               __global float* out_triangle_normals) {
  const uint t = get_global_id(0);
  if (t >= triangle_count) return;
  const float3 a = vload3(triangles[3 * t], positions);
  const float3 b = vload3(triangles[3 * t + 1], positions);
  const float3 c = vload3(triangles[3 * t + 2], positions);
  vstore3(cross(b - a, c - a), t, out_triangle_normals);
}

__kernel void vertex_normals(const uint vertex_count,
                             __global const float* triangle_normals,
                             __global const uint* adjacency_offsets,
                             __global const uint* adjacency_triangles,
                             __global const float* fallback_normals,
                             __global float* out_normals) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  float3 sum = (float3)(0.0f);
  const uint end = adjacency_offsets[v + 1];
  for (uint i = adjacency_offsets[v]; i < end; ++i)
    sum += vload3(adjacency_triangles[i], triangle_normals);
  const float len = sqrt(dot(sum, sum));
  // isfinite: a cross product past FLT_MAX (a pose scaled or moved absurdly
  // far) is inf, and inf / inf NaN; a contracted fma gives inf where the
  // reference's plain products give NaN, so both test the length.
  vstore3(len > FLT_MIN && isfinite(len) ? sum / len
                                         : vload3(v, fallback_normals),
          v, out_normals);
}
