#include "trace/embree.h"

#include <fmt/core.h>

#include <pmmintrin.h>
#include <xmmintrin.h>

#include <cstring>
#include <limits>

namespace microsim::embree {

// ---- flush-to-zero / denormals-are-zero ----------------------------------------------------------------

FlushDenormalsScope::FlushDenormalsScope() : saved_csr_(_mm_getcsr()) {
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

FlushDenormalsScope::~FlushDenormalsScope() { _mm_setcsr(saved_csr_); }

bool FlushDenormalsScope::active_in_this_thread() {
  return _MM_GET_FLUSH_ZERO_MODE() == _MM_FLUSH_ZERO_ON && _MM_GET_DENORMALS_ZERO_MODE() == _MM_DENORMALS_ZERO_ON;
}

// ---- device --------------------------------------------------------------------------------------------

namespace {
const char* error_name(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE: return "no error";
    case RTC_ERROR_UNKNOWN: return "unknown error";
    case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
    case RTC_ERROR_CANCELLED: return "cancelled";
  }
  return "unrecognised error code";
}
}  // namespace

Device::Device(const std::string& config) {
  device_ = rtcNewDevice(config.empty() ? nullptr : config.c_str());
  if (!device_) {
    throw EmbreeError(fmt::format("rtcNewDevice(\"{}\") failed: {}", config, error_name(rtcGetDeviceError(nullptr))));
  }
  rtcSetDeviceErrorFunction(device_, &Device::on_error, this);
}

Device::~Device() {
  if (device_) rtcReleaseDevice(device_);
}

void Device::on_error(void* user, RTCError code, const char* message) {
  auto* self = static_cast<Device*>(user);
  std::lock_guard lock(self->mutex_);
  if (self->error_code_ != RTC_ERROR_NONE) return;  // keep the first error: later ones are usually consequences
  self->error_code_ = code;
  self->error_message_ = fmt::format("{} ({})", message ? message : "", error_name(code));
}

void Device::check(std::string_view what) const {
  std::lock_guard lock(mutex_);
  if (error_code_ == RTC_ERROR_NONE) return;
  const std::string message = fmt::format("Embree error in {}: {}", what, error_message_);
  error_code_ = RTC_ERROR_NONE;
  error_message_.clear();
  throw EmbreeError(message);
}

std::string Device::pending_error() const {
  std::lock_guard lock(mutex_);
  return error_message_;
}

// ---- scene ---------------------------------------------------------------------------------------------

namespace {
RTCBuildQuality to_rtc(BuildQuality q) {
  switch (q) {
    case BuildQuality::low: return RTC_BUILD_QUALITY_LOW;
    case BuildQuality::medium: return RTC_BUILD_QUALITY_MEDIUM;
    case BuildQuality::high: return RTC_BUILD_QUALITY_HIGH;
  }
  return RTC_BUILD_QUALITY_MEDIUM;
}
}  // namespace

Scene::Scene(const Device& device, BuildQuality quality, bool robust) : device_(device) {
  scene_ = rtcNewScene(device_.handle());
  device_.check("rtcNewScene");
  if (!scene_) throw EmbreeError("rtcNewScene returned no scene");
  rtcSetSceneFlags(scene_, robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  rtcSetSceneBuildQuality(scene_, to_rtc(quality));
  device_.check("rtcSetSceneFlags/rtcSetSceneBuildQuality");
}

Scene::~Scene() {
  if (scene_) rtcReleaseScene(scene_);
}

unsigned int Scene::add_triangles(std::span<const float> vertices, std::span<const std::uint32_t> indices) {
  if (committed_) throw EmbreeError("Scene::add_triangles after commit()");
  if (vertices.size() % 3 != 0 || indices.size() % 3 != 0) {
    throw EmbreeError("Scene::add_triangles: buffer sizes must be multiples of 3");
  }
  const std::size_t vertex_count = vertices.size() / 3, triangle_count = indices.size() / 3;
  for (std::size_t i = 0; i < indices.size(); ++i) {
    if (indices[i] >= vertex_count) {
      throw EmbreeError(fmt::format("Scene::add_triangles: triangle {} uses vertex {} of {}", i / 3, indices[i],
                                    vertex_count));
    }
  }
  RTCGeometry geom = rtcNewGeometry(device_.handle(), RTC_GEOMETRY_TYPE_TRIANGLE);
  device_.check("rtcNewGeometry(TRIANGLE)");
  // Embree may read vertex data with 16-byte SSE loads: the last vertex needs 4 bytes of padding, which
  // rtcSetNewGeometryBuffer's own allocation provides.
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertex_count));
  auto* ib = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                 3 * sizeof(std::uint32_t), triangle_count));
  if (!vb || !ib) {
    rtcReleaseGeometry(geom);
    device_.check("rtcSetNewGeometryBuffer");
    throw EmbreeError("rtcSetNewGeometryBuffer returned no buffer");
  }
  std::memcpy(vb, vertices.data(), vertices.size_bytes());
  std::memcpy(ib, indices.data(), indices.size_bytes());
  rtcCommitGeometry(geom);
  const unsigned int id = rtcAttachGeometry(scene_, geom);
  rtcReleaseGeometry(geom);  // the scene holds its own reference
  device_.check("rtcCommitGeometry/rtcAttachGeometry(TRIANGLE)");
  return id;
}

unsigned int Scene::add_user_geometry(unsigned int primitive_count, void* user_ptr,
                                      const UserGeometryCallbacks& callbacks) {
  if (committed_) throw EmbreeError("Scene::add_user_geometry after commit()");
  if (!callbacks.bounds || !callbacks.intersect) {
    throw EmbreeError("Scene::add_user_geometry: bounds and intersect callbacks are required");
  }
  RTCGeometry geom = rtcNewGeometry(device_.handle(), RTC_GEOMETRY_TYPE_USER);
  device_.check("rtcNewGeometry(USER)");
  rtcSetGeometryUserPrimitiveCount(geom, primitive_count);
  rtcSetGeometryUserData(geom, user_ptr);
  rtcSetGeometryBoundsFunction(geom, callbacks.bounds, user_ptr);
  rtcSetGeometryIntersectFunction(geom, callbacks.intersect);
  if (callbacks.occluded) rtcSetGeometryOccludedFunction(geom, callbacks.occluded);
  rtcCommitGeometry(geom);
  const unsigned int id = rtcAttachGeometry(scene_, geom);
  rtcReleaseGeometry(geom);
  device_.check("rtcCommitGeometry/rtcAttachGeometry(USER)");
  return id;
}

void Scene::commit() {
  rtcCommitScene(scene_);
  device_.check("rtcCommitScene");
  committed_ = true;
}

RTCBounds Scene::bounds() const {
  RTCBounds b;
  rtcGetSceneBounds(scene_, &b);
  device_.check("rtcGetSceneBounds");
  return b;
}


std::optional<Hit> Scene::intersect(const Vec3<float>& origin, const Vec3<float>& dir, float tnear,
                                    float tfar) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh = make_ray_hit(origin, dir, tnear, tfar);
  rtcIntersect1(scene_, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  return Hit{rh.ray.tfar, rh.hit.primID, rh.hit.geomID, Vec3<float>(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z),
             rh.hit.u, rh.hit.v};
}

bool Scene::occluded(const Vec3<float>& origin, const Vec3<float>& dir, float tnear, float tfar) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray = make_ray_hit(origin, dir, tnear, tfar).ray;
  rtcOccluded1(scene_, &context, &ray);
  // Embree sets tfar to -inf when the ray is occluded.
  return ray.tfar == -std::numeric_limits<float>::infinity();
}

}  // namespace microsim::embree
