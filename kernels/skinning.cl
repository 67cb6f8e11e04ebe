// Geometric skinning: linear blend (LBS) and dual quaternion (DQS, Kavan et
// al. 2008), and its inverse point by point. OpenCL C 1.2, self-contained.
// CPU reference: lib/src/skinning/skinning.cpp.
//
// Layout: positions/normals are packed float triples (vload3/vstore3);
// influences are compressed rows (offsets[v] .. offsets[v+1]-1), sorted by
// decreasing weight so the first one is the DQS pivot.
// LBS joints: 3 float4 rows of the 3x4 matrix each.
// DQS joints: 2 float4 each, real (x y z w) then dual (x y z w).

// Rotates v by the unit quaternion q (xyz = vector part, w = scalar).
float3 quat_rotate(float4 q, float3 v) {
  const float3 u = q.xyz;
  const float3 t = 2.0f * cross(u, v);
  return v + q.w * t + cross(u, t);
}

// Vertex v's blended 3x4 matrix (LBS), as three rows.
void blend_rows(const uint v, __global const uint* influence_offsets,
                __global const uint* influence_joints,
                __global const float* influence_weights,
                __global const float4* joint_rows, float4* r0, float4* r1,
                float4* r2) {
  *r0 = (float4)(0.0f);
  *r1 = (float4)(0.0f);
  *r2 = (float4)(0.0f);
  const uint end = influence_offsets[v + 1];
  for (uint i = influence_offsets[v]; i < end; ++i) {
    const float w = influence_weights[i];
    const uint j = influence_joints[i];
    *r0 += w * joint_rows[3 * j];
    *r1 += w * joint_rows[3 * j + 1];
    *r2 += w * joint_rows[3 * j + 2];
  }
}

// Vertex v's blended unit dual quaternion (DQS): its rotation and its
// translation.
void blend_dual_quaternion(const uint v, __global const uint* influence_offsets,
                           __global const uint* influence_joints,
                           __global const float* influence_weights,
                           __global const float4* joint_dqs, float4* rotation,
                           float3* translation) {
  const uint begin = influence_offsets[v];
  const uint end = influence_offsets[v + 1];
  const float4 pivot = joint_dqs[2 * influence_joints[begin]];
  float4 real = (float4)(0.0f);
  float4 dual = (float4)(0.0f);
  for (uint i = begin; i < end; ++i) {
    const uint j = influence_joints[i];
    const float4 qr = joint_dqs[2 * j];
    const float4 qd = joint_dqs[2 * j + 1];
    // Antipodality: q and -q are the same rotation; blend on the pivot's side.
    const float w = dot(qr, pivot) < 0.0f ? -influence_weights[i]
                                          : influence_weights[i];
    real += w * qr;
    dual += w * qd;
  }
  const float norm = sqrt(dot(real, real));
  real /= norm;
  dual /= norm;
  *rotation = real;
  // t = 2 * vec(dual * conj(real))
  *translation =
      2.0f * (real.w * dual.xyz - dual.w * real.xyz + cross(real.xyz, dual.xyz));
}

__kernel void skin_lbs(const uint vertex_count,
                       __global const float* rest_positions,
                       __global const float* rest_normals,
                       __global const uint* influence_offsets,
                       __global const uint* influence_joints,
                       __global const float* influence_weights,
                       __global const float4* joint_rows,
                       __global float* out_positions,
                       __global float* out_normals) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  float4 r0, r1, r2;
  blend_rows(v, influence_offsets, influence_joints, influence_weights,
             joint_rows, &r0, &r1, &r2);
  const float4 p = (float4)(vload3(v, rest_positions), 1.0f);
  vstore3((float3)(dot(r0, p), dot(r1, p), dot(r2, p)), v, out_positions);

  // Normals by the cofactor matrix (inverse transpose up to scale).
  const float3 n = vload3(v, rest_normals);
  const float3 a = r0.xyz;
  const float3 b = r1.xyz;
  const float3 c = r2.xyz;
  float3 m = (float3)(dot(cross(b, c), n), dot(cross(c, a), n),
                      dot(cross(a, b), n));
  const float len = sqrt(dot(m, m));
  m = len > FLT_MIN && isfinite(len) ? m / len : n;  // inf: scaled past FLT_MAX
  vstore3(m, v, out_normals);
}

__kernel void skin_dqs(const uint vertex_count,
                       __global const float* rest_positions,
                       __global const float* rest_normals,
                       __global const uint* influence_offsets,
                       __global const uint* influence_joints,
                       __global const float* influence_weights,
                       __global const float4* joint_dqs,
                       __global float* out_positions,
                       __global float* out_normals) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  float4 real;
  float3 t;
  blend_dual_quaternion(v, influence_offsets, influence_joints,
                        influence_weights, joint_dqs, &real, &t);
  const float3 p = vload3(v, rest_positions);
  vstore3(quat_rotate(real, p) + t, v, out_positions);
  vstore3(quat_rotate(real, vload3(v, rest_normals)), v, out_normals);
}

// The inverse of skinning, point by point (unskinPoints in the CPU
// reference): posed points carried back to rest space by the inverse of each
// vertex's blended transform. History-dependent tracking keeps its vertices
// in rest space between frames with them.
__kernel void unskin_lbs(const uint vertex_count, __global const float* posed,
                         __global const uint* influence_offsets,
                         __global const uint* influence_joints,
                         __global const float* influence_weights,
                         __global const float4* joint_rows,
                         __global float* out_rest) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  float4 r0, r1, r2;
  blend_rows(v, influence_offsets, influence_joints, influence_weights,
             joint_rows, &r0, &r1, &r2);
  const float3 x = vload3(v, posed);
  const float3 y = x - (float3)(r0.w, r1.w, r2.w);
  // The inverse by the cofactors; a singular blend keeps the point.
  const float3 bc = cross(r1.xyz, r2.xyz);
  const float3 ca = cross(r2.xyz, r0.xyz);
  const float3 ab = cross(r0.xyz, r1.xyz);
  const float det = dot(r0.xyz, bc);
  vstore3(fabs(det) > FLT_MIN && isfinite(det)
              ? (y.x * bc + y.y * ca + y.z * ab) / det
              : x,
          v, out_rest);
}

__kernel void unskin_dqs(const uint vertex_count, __global const float* posed,
                         __global const uint* influence_offsets,
                         __global const uint* influence_joints,
                         __global const float* influence_weights,
                         __global const float4* joint_dqs,
                         __global float* out_rest) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  float4 real;
  float3 t;
  blend_dual_quaternion(v, influence_offsets, influence_joints,
                        influence_weights, joint_dqs, &real, &t);
  const float4 inverse = (float4)(-real.xyz, real.w);
  vstore3(quat_rotate(inverse, vload3(v, posed) - t), v, out_rest);
}
