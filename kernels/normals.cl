// Area-weighted vertex normals from deformed positions. OpenCL C 1.2,
// self-contained. CPU reference: lib/src/vertex_normals.cpp.
//
// A gather per vertex over its incident triangles (compressed rows built once
// on the host), so no atomics: each vertex sums the cross products of its
// triangles in adjacency order and normalizes; a vanishing or overflowing
// sum takes the fallback normal (the skinned normal). Each adjacency entry
// holds its triangle's three corners in the triangle's order
// (VertexTriangleAdjacency::corners), read in sequence: no triangle index
// to load first.

__kernel void vertex_normals(const uint vertex_count,
                             __global const float* positions,
                             __global const uint* adjacency_offsets,
                             __global const int* adjacency_corners,
                             __global const float* fallback_normals,
                             __global float* out_normals) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  float3 sum = (float3)(0.0f);
  const uint end = adjacency_offsets[v + 1];
  for (uint i = adjacency_offsets[v]; i < end; ++i) {
    const float3 a = vload3(adjacency_corners[3 * i], positions);
    const float3 b = vload3(adjacency_corners[3 * i + 1], positions);
    const float3 c = vload3(adjacency_corners[3 * i + 2], positions);
    sum += cross(b - a, c - a);
  }
  const float len = sqrt(dot(sum, sum));
  // isfinite: a cross product past FLT_MAX (a pose scaled or moved absurdly
  // far) is inf, and inf / inf NaN; a contracted fma gives inf where the
  // reference's plain products give NaN, so both test the length.
  vstore3(len > FLT_MIN && isfinite(len) ? sum / len
                                         : vload3(v, fallback_normals),
          v, out_normals);
}
