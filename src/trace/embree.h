// microsim: Embree 3 behind one small RAII wrapper (no globals).
//
// - Device: owns an RTCDevice. Embree reports errors through a callback; throwing from inside Embree's
//   C API is not allowed, so the callback RECORDS the first error (code + message) and every wrapper call
//   checks afterwards and throws EmbreeError naming the call that failed.
// - Scene: owns an RTCScene built with RTC_SCENE_FLAG_ROBUST (no cracks between neighbouring triangles,
//   at a small speed cost) and a chosen build quality; triangle geometry from vertex/index buffers (copied
//   into Embree-owned buffers), user geometry from callbacks; commit(); then intersect() per ray.
// - FlushDenormalsScope: Embree's documentation asks every thread that traces to run with
//   flush-to-zero and denormals-are-zero (MXCSR); the tracing loops open one such scope at the start of
//   every TBB task body. It restores the previous mode on exit, so other code in the thread is unaffected.
//
// Rays are single-ray rtcIntersect1 calls (no streams, no packets): the tracer's loop is plain, and each
// ray's result depends on that ray only.
#pragma once

#include "core/errors.h"

#include "core/math.h"

#include <embree3/rtcore.h>

#include <cstdint>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace microsim::embree {

struct EmbreeError : InternalError {
  using InternalError::InternalError;
};

// Sets FTZ and DAZ in the calling thread for its lifetime, restoring the previous MXCSR afterwards.
class FlushDenormalsScope {
public:
  FlushDenormalsScope();
  ~FlushDenormalsScope();
  FlushDenormalsScope(const FlushDenormalsScope&) = delete;
  FlushDenormalsScope& operator=(const FlushDenormalsScope&) = delete;
  // Whether FTZ and DAZ are both set in the calling thread now (for tests).
  static bool active_in_this_thread();

private:
  unsigned int saved_csr_;
};

class Device {
public:
  // `config` is Embree's device configuration string ("" = defaults; e.g. "threads=1,verbose=0").
  explicit Device(const std::string& config = "");
  ~Device();
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  RTCDevice handle() const { return device_; }
  // Throws EmbreeError("<what>: <Embree's message>") if Embree reported an error since the last check.
  void check(std::string_view what) const;
  // The first recorded error message not yet consumed by check() ("" if none).
  std::string pending_error() const;

private:
  static void on_error(void* user, RTCError code, const char* message);
  RTCDevice device_ = nullptr;
  mutable std::mutex mutex_;
  mutable RTCError error_code_ = RTC_ERROR_NONE;
  mutable std::string error_message_;
};

enum class BuildQuality { low, medium, high };

// One ray's closest hit. Ng is Embree's (unnormalised) geometric normal for triangles, or whatever the
// user geometry wrote (the quadric writes its unit analytic normal).
struct Hit {
  float t;
  unsigned int prim_id;
  unsigned int geom_id;
  Vec3<float> Ng;
  float u, v;
};

// The callbacks of an Embree user geometry (see rtcSetGeometry{Bounds,Intersect,Occluded}Function).
struct UserGeometryCallbacks {
  RTCBoundsFunction bounds;
  RTCIntersectFunctionN intersect;
  RTCOccludedFunctionN occluded;
};

class Scene {
public:
  explicit Scene(const Device& device, BuildQuality quality = BuildQuality::high, bool robust = true);
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  // Adds a triangle mesh: `vertices` holds x,y,z per vertex, `indices` three vertex indices per triangle.
  // The data are copied. Returns the geometry id. Throws EmbreeError on an out-of-range index.
  unsigned int add_triangles(std::span<const float> vertices, std::span<const std::uint32_t> indices);
  // Adds a user geometry of `primitive_count` primitives; `user_ptr` is passed to the callbacks and must
  // outlive the scene.
  unsigned int add_user_geometry(unsigned int primitive_count, void* user_ptr, const UserGeometryCallbacks& callbacks);
  // Builds the acceleration structure. Must be called once after the last add_*, before tracing.
  void commit();
  bool committed() const { return committed_; }

  // Closest hit along origin + t dir with t in [tnear, tfar]; nullopt for a miss. Thread-safe after
  // commit(). `dir` need not be normalised (t is in units of |dir|).
  std::optional<Hit> intersect(const Vec3<float>& origin, const Vec3<float>& dir, float tnear, float tfar) const;
  // Whether anything is hit with t in [tnear, tfar].
  bool occluded(const Vec3<float>& origin, const Vec3<float>& dir, float tnear, float tfar) const;

  RTCScene handle() const { return scene_; }
  const Device& device() const { return device_; }
  // The scene's bounds after commit().
  RTCBounds bounds() const;

private:
  const Device& device_;
  RTCScene scene_ = nullptr;
  bool committed_ = false;
};

// A ray for rtcIntersect1 from origin along dir with t in [tnear, tfar], its hit cleared (no geometry, no
// instance). Inline: it sits in every tracing loop, the benchmarks' raw baseline included.
inline RTCRayHit make_ray_hit(float ox, float oy, float oz, float dx, float dy, float dz, float tnear, float tfar) {
  RTCRayHit rh;
  rh.ray.org_x = ox;
  rh.ray.org_y = oy;
  rh.ray.org_z = oz;
  rh.ray.dir_x = dx;
  rh.ray.dir_y = dy;
  rh.ray.dir_z = dz;
  rh.ray.tnear = tnear;
  rh.ray.tfar = tfar;
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xffffffffu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}
inline RTCRayHit make_ray_hit(const Vec3<float>& origin, const Vec3<float>& dir, float tnear, float tfar) {
  return make_ray_hit(origin.x(), origin.y(), origin.z(), dir.x(), dir.y(), dir.z(), tnear, tfar);
}

}  // namespace microsim::embree
