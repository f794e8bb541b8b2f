// Rigid transforms as ROS writes them: { translation: {x, y, z}, rotation: {x, y, z, w} } (a unit quaternion).
// A transform of `parent` <- `child` (a geometry_msgs/TransformStamped with header.frame_id parent and
// child_frame_id child) maps a point in child's coordinates to parent's: p_parent = R p_child + t.
export const IDENTITY = Object.freeze({ translation: { x: 0, y: 0, z: 0 }, rotation: { x: 0, y: 0, z: 0, w: 1 } });

export function multiplyQuaternions(a, b) {
  return {
    x: a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
    y: a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
    z: a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
    w: a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
  };
}

export function normalize(q) {
  const n = Math.hypot(q.x, q.y, q.z, q.w) || 1;
  return { x: q.x / n, y: q.y / n, z: q.z / n, w: q.w / n };
}

// v rotated by the unit quaternion q.
export function rotate(q, v) {
  // t = 2 q.xyz × v; v' = v + w t + q.xyz × t
  const tx = 2 * (q.y * v.z - q.z * v.y);
  const ty = 2 * (q.z * v.x - q.x * v.z);
  const tz = 2 * (q.x * v.y - q.y * v.x);
  return {
    x: v.x + q.w * tx + (q.y * tz - q.z * ty),
    y: v.y + q.w * ty + (q.z * tx - q.x * tz),
    z: v.z + q.w * tz + (q.x * ty - q.y * tx),
  };
}

// a ∘ b: first b, then a (a: A <- B, b: B <- C gives A <- C).
export function compose(a, b) {
  const moved = rotate(a.rotation, b.translation);
  return {
    translation: { x: a.translation.x + moved.x, y: a.translation.y + moved.y, z: a.translation.z + moved.z },
    rotation: normalize(multiplyQuaternions(a.rotation, b.rotation)),
  };
}

export function invert(a) {
  const r = { x: -a.rotation.x, y: -a.rotation.y, z: -a.rotation.z, w: a.rotation.w };
  const t = rotate(r, a.translation);
  return { translation: { x: -t.x, y: -t.y, z: -t.z }, rotation: r };
}

export function apply(a, point) {
  const p = rotate(a.rotation, point);
  return { x: p.x + a.translation.x, y: p.y + a.translation.y, z: p.z + a.translation.z };
}

// Roll, pitch, yaw (radians; fixed axes x, y, z, as tf's getRPY).
export function rpyOf(q) {
  const roll = Math.atan2(2 * (q.w * q.x + q.y * q.z), 1 - 2 * (q.x * q.x + q.y * q.y));
  const pitch = Math.asin(Math.max(-1, Math.min(1, 2 * (q.w * q.y - q.z * q.x))));
  const yaw = Math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z));
  return { roll, pitch, yaw };
}

// A transform from a message's (plain numbers; a missing w reads as 1, the rotation normalized).
export function transformOf(message) {
  const t = message?.translation ?? {};
  const r = message?.rotation ?? {};
  const num = (v, d) => (Number.isFinite(v) ? v : d);
  return {
    translation: { x: num(t.x, 0), y: num(t.y, 0), z: num(t.z, 0) },
    rotation: normalize({ x: num(r.x, 0), y: num(r.y, 0), z: num(r.z, 0), w: num(r.w, 1) }),
  };
}
