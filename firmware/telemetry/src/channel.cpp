#include "zerog/telemetry/channel.hpp"

#include <time.h>

#include <chrono>
#include <vector>

#include "dds/dds.h"
#include "zerog/handover/clock.hpp"

namespace zerog::telemetry {

namespace {

using handover::monotonic_ns;

BodyParamsValue body_value(const control::BodyParams& body) noexcept {
  BodyParamsValue v;
  v.mass_kg = body.mass_kg;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) v.inertia_body_kgm2[3 * r + c] = body.inertia_body_kgm2(r, c);
  return v;
}

control::BodyParams body_params(const BodyParamsValue& v) noexcept {
  control::BodyParams body;
  body.mass_kg = v.mass_kg;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) body.inertia_body_kgm2(r, c) = v.inertia_body_kgm2[3 * r + c];
  return body;
}

std::string dds_error(const std::string& what, dds_return_t rc) {
  return "telemetry: " + what + " failed: " + dds_strretcode(rc);
}

}  // namespace

struct TelemetryChannel::Dds {
  dds_entity_t domain = 0;
  dds_entity_t participant = 0;
  dds_entity_t wrench = 0, imu = 0, robot = 0, command = 0, body = 0, timing = 0;
  dds_entity_t health = 0, model = 0;
  // ROS 2 topics (config.ros2).
  dds_entity_t ros_wrench = 0, ros_wrench_at_eval = 0, ros_wrench_predicted = 0,
               ros_wrench_contact = 0, ros_imu = 0, ros_joints = 0, ros_sensor_pose = 0,
               ros_body_pose = 0, ros_body_twist = 0, ros_diagnostics = 0;

  ~Dds() {
    if (participant > 0) dds_delete(participant);
    if (domain > 0) dds_delete(domain);
  }
};

TelemetryChannel::TelemetryChannel(TelemetryConfig config, ModelIdentityInfo model,
                                   control::BodyParams body)
    : config_(std::move(config)), model_(std::move(model)), ring_(std::make_unique<Ring>()) {
  pub_.body = body;
  body_params_.publish(body_value(body));
}

TelemetryChannel::~TelemetryChannel() { stop(); }

Status TelemetryChannel::start() {
  if (started_) return {};
  if (Status st = check_config(config_); !st.ok()) return st;
  const auto failed = [](std::string why) {
    return Status(StatusCode::system_error, std::move(why));
  };
  auto dds = std::make_unique<Dds>();
  const std::string xml = cyclone_xml(config_);
  const auto domain_id = static_cast<dds_domainid_t>(config_.domain_id);
  dds->domain = dds_create_domain(domain_id, xml.c_str());
  if (dds->domain < 0) {
    const dds_return_t rc = dds->domain;
    dds->domain = 0;
    std::string why = dds_error("dds_create_domain(" + std::to_string(config_.domain_id) + ")", rc);
    if (rc == DDS_RETCODE_PRECONDITION_NOT_MET)
      why += " (the domain already exists in this process)";
    return failed(why + "; configuration: " + xml);
  }
  dds->participant = dds_create_participant(domain_id, nullptr, nullptr);
  if (dds->participant < 0) {
    const dds_return_t rc = dds->participant;
    dds->participant = 0;
    return failed(dds_error("dds_create_participant", rc));
  }

  // High-rate streams: best-effort, keep-last 1, volatile. State: reliable, transient-local.
  dds_qos_t* stream_qos = dds_create_qos();
  dds_qset_reliability(stream_qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(stream_qos, DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(stream_qos, DDS_DURABILITY_VOLATILE);
  dds_qos_t* state_qos = dds_create_qos();
  dds_qset_reliability(state_qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(state_qos, DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(state_qos, DDS_DURABILITY_TRANSIENT_LOCAL);

  std::string error;
  const auto writer = [&](const dds_topic_descriptor_t* desc, const char* suffix,
                          const dds_qos_t* qos, dds_entity_t& out) {
    if (!error.empty()) return;
    const std::string name = topic_name(suffix);
    const dds_entity_t topic = dds_create_topic(dds->participant, desc, name.c_str(), qos, nullptr);
    if (topic < 0) {
      error = dds_error("dds_create_topic(" + name + ")", topic);
      return;
    }
    out = dds_create_writer(dds->participant, topic, qos, nullptr);
    if (out < 0) error = dds_error("dds_create_writer(" + name + ")", out);
  };
  writer(&zerog_telemetry_WrenchSample_desc, "wrench", stream_qos, dds->wrench);
  writer(&zerog_telemetry_ImuSample_desc, "imu", stream_qos, dds->imu);
  writer(&zerog_telemetry_RobotSample_desc, "robot", stream_qos, dds->robot);
  writer(&zerog_telemetry_CommandSample_desc, "command", stream_qos, dds->command);
  writer(&zerog_telemetry_BodySample_desc, "body", stream_qos, dds->body);
  writer(&zerog_telemetry_TimingSample_desc, "timing", stream_qos, dds->timing);
  writer(&zerog_telemetry_Health_desc, "health", state_qos, dds->health);
  writer(&zerog_telemetry_ModelIdentity_desc, "model", state_qos, dds->model);
  if (config_.ros2) {
    // ROS 2's QoS profiles (rmw/qos_profiles.h): rmw_qos_profile_sensor_data (best-effort,
    // keep-last 5, volatile) for the streams; transient-local (reliable, keep-last 1,
    // transient-local: rclcpp's QoS(1).transient_local()) for the diagnostics.
    dds_qos_t* sensor_qos = dds_create_qos();
    dds_qset_reliability(sensor_qos, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(sensor_qos, DDS_HISTORY_KEEP_LAST, 5);
    dds_qset_durability(sensor_qos, DDS_DURABILITY_VOLATILE);
    const auto ros_writer = [&](const dds_topic_descriptor_t* desc, const char* name,
                                const dds_qos_t* qos, dds_entity_t& out) {
      if (!error.empty()) return;
      const std::string topic_name = ros_dds_topic(config_.ros_namespace, name);
      const dds_entity_t topic =
          dds_create_topic(dds->participant, desc, topic_name.c_str(), qos, nullptr);
      if (topic < 0) {
        error = dds_error("dds_create_topic(" + topic_name + ")", topic);
        return;
      }
      out = dds_create_writer(dds->participant, topic, qos, nullptr);
      if (out < 0) error = dds_error("dds_create_writer(" + topic_name + ")", out);
    };
    namespace t = ros_topic;
    const auto* wrench_desc = &geometry_msgs_msg_dds__WrenchStamped__desc;
    ros_writer(wrench_desc, t::kWrench, sensor_qos, dds->ros_wrench);
    ros_writer(wrench_desc, t::kWrenchAtEval, sensor_qos, dds->ros_wrench_at_eval);
    ros_writer(wrench_desc, t::kWrenchPredicted, sensor_qos, dds->ros_wrench_predicted);
    ros_writer(wrench_desc, t::kWrenchContact, sensor_qos, dds->ros_wrench_contact);
    ros_writer(&sensor_msgs_msg_dds__Imu__desc, t::kImu, sensor_qos, dds->ros_imu);
    ros_writer(&sensor_msgs_msg_dds__JointState__desc, t::kJointStates, sensor_qos,
               dds->ros_joints);
    const auto* pose_desc = &geometry_msgs_msg_dds__PoseStamped__desc;
    ros_writer(pose_desc, t::kSensorPose, sensor_qos, dds->ros_sensor_pose);
    ros_writer(pose_desc, t::kBodyPose, sensor_qos, dds->ros_body_pose);
    ros_writer(&geometry_msgs_msg_dds__TwistStamped__desc, t::kBodyTwist, sensor_qos,
               dds->ros_body_twist);
    dds_qset_history(state_qos, DDS_HISTORY_KEEP_LAST, 1);
    ros_writer(&diagnostic_msgs_msg_dds__DiagnosticArray__desc, t::kDiagnostics, state_qos,
               dds->ros_diagnostics);
    dds_delete_qos(sensor_qos);
    pub_.ros_frames = std::make_unique<Ros2Frames>(config_);
    pub_.ros_messages = std::make_unique<Ros2CycleMessages>();
  }
  dds_delete_qos(stream_qos);
  dds_delete_qos(state_qos);
  if (!error.empty()) return failed(error);

  std::vector<char*> storage;
  const zerog_telemetry_ModelIdentity identity = model_identity_sample(model_, storage);
  if (const dds_return_t rc = dds_write(dds->model, &identity); rc < 0)
    return failed(dds_error("dds_write(" + topic_name("model") + ")", rc));

  dds_ = std::move(dds);
  stop_.store(false, std::memory_order_relaxed);
  started_ = true;
  publish_health(true);
  thread_ = std::thread([this] { publisher_loop(); });
  return {};
}

void TelemetryChannel::stop(double ack_timeout_s) {
  if (!started_) return;
  paused_.store(false, std::memory_order_relaxed);
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  publish_health(true);
  const auto timeout = static_cast<dds_duration_t>(ack_timeout_s * 1e9);
  dds_wait_for_acks(dds_->health, timeout);
  dds_wait_for_acks(dds_->model, timeout);
  if (dds_->ros_diagnostics > 0) dds_wait_for_acks(dds_->ros_diagnostics, timeout);
  dds_.reset();
  started_ = false;
}

bool TelemetryChannel::offer(const loop::CycleRecord& record, std::int64_t received_ns) noexcept {
  offer_slot_.record = record;
  offer_slot_.received_ns = received_ns;
  return ring_->try_push(offer_slot_);
}

void TelemetryChannel::set_body_params(const control::BodyParams& body) noexcept {
  body_params_.publish(body_value(body));
}

ChannelCounters TelemetryChannel::counters() const {
  ChannelCounters c;
  c.telemetry_drops = ring_->dropped();
  c.records_offered = ring_->pushed() + c.telemetry_drops;
  c.records_published = published_.records.load(std::memory_order_acquire);
  c.write_errors = published_.write_errors.load(std::memory_order_relaxed);
  c.health_published = published_.health.load(std::memory_order_relaxed);
  return c;
}

int TelemetryChannel::subscribers() const {
  if (!started_) return 0;
  dds_publication_matched_status_t status{};
  if (dds_get_publication_matched_status(dds_->wrench, &status) < 0) return 0;
  int count = static_cast<int>(status.current_count);
  if (dds_->ros_wrench > 0 && dds_get_publication_matched_status(dds_->ros_wrench, &status) >= 0)
    count += static_cast<int>(status.current_count);
  return count;
}

void TelemetryChannel::publisher_loop() {
  const auto poll =
      std::chrono::nanoseconds(static_cast<std::int64_t>(config_.poll_period_s * 1e9));
  for (;;) {
    const bool stopping = stop_.load(std::memory_order_acquire);
    bool took = false;
    if (!paused_.load(std::memory_order_relaxed)) {
      // Health between batches, so a state change is published within a batch of records.
      for (int i = 0; i < 64 && drain_one(); ++i) took = true;
    }
    publish_health(false);
    if (stopping && !took) break;  // stop(): the ring is drained
    if (!took) std::this_thread::sleep_for(poll);
  }
}

bool TelemetryChannel::drain_one() {
  if (!ring_->try_pop(pub_.slot)) return false;
  BodyParamsValue body;
  if (body_params_.read(body) == handover::LatestRead::fresh) pub_.body = body_params(body);
  const loop::CycleRecord& r = pub_.slot.record;
  RuntimeHealth runtime;
  if (runtime_health_.read(runtime) != handover::LatestRead::empty) pub_.health_in = runtime;

  double period_s = 0.0;
  if (pub_.have_newest && r.cycle == pub_.previous_cycle + 1) {
    if (pub_.slot.received_ns != 0 && pub_.previous_received_ns != 0)
      period_s = static_cast<double>(pub_.slot.received_ns - pub_.previous_received_ns) * 1e-9;
    else if (pub_.slot.received_ns == 0)
      period_s = r.t_s - pub_.previous_t_s;
  }
  pub_.previous_cycle = r.cycle;
  pub_.previous_received_ns = pub_.slot.received_ns;
  pub_.previous_t_s = r.t_s;

  std::uint64_t errors = 0;
  const auto write = [&errors](dds_entity_t w, const void* sample) {
    if (dds_write(w, sample) < 0) ++errors;
  };
  const WrenchSample wrench = to_wrench(r);
  write(dds_->wrench, &wrench);
  const ImuSample imu = to_imu(r);
  write(dds_->imu, &imu);
  const RobotSample robot = to_robot(r);
  write(dds_->robot, &robot);
  const CommandSample command = to_command(r, pub_.body);
  write(dds_->command, &command);
  const BodySample body_sample = to_body(r, pub_.body);
  write(dds_->body, &body_sample);
  const TimingSample timing =
      to_timing(r, period_s, config_.nominal_period_s, pub_.health_in.datagrams_lost);
  write(dds_->timing, &timing);
  if (pub_.ros_messages != nullptr) {
    Ros2CycleMessages& m = *pub_.ros_messages;
    to_ros2(r, pub_.body, *pub_.ros_frames, m);
    write(dds_->ros_wrench, &m.wrench);
    write(dds_->ros_wrench_at_eval, &m.wrench_at_eval);
    write(dds_->ros_wrench_predicted, &m.wrench_predicted);
    write(dds_->ros_wrench_contact, &m.wrench_contact);
    write(dds_->ros_imu, &m.imu);
    write(dds_->ros_joints, &m.joints);
    write(dds_->ros_sensor_pose, &m.sensor_pose);
    write(dds_->ros_body_pose, &m.body_pose);
    write(dds_->ros_body_twist, &m.body_twist);
  }
  if (errors != 0) published_.write_errors.fetch_add(errors, std::memory_order_relaxed);

  pub_.newest = r;
  pub_.have_newest = true;
  published_.records.fetch_add(1, std::memory_order_release);
  return true;
}

void TelemetryChannel::publish_health(bool force) {
  RuntimeHealth runtime;
  if (runtime_health_.read(runtime) != handover::LatestRead::empty) pub_.health_in = runtime;
  const ChannelCounters c = counters();
  const std::int64_t now = monotonic_ns();
  const std::uint8_t state = pub_.have_newest ? static_cast<std::uint8_t>(pub_.newest.state) : 0xFF;
  const std::uint8_t fault = pub_.have_newest ? static_cast<std::uint8_t>(pub_.newest.fault) : 0xFF;
  const bool changed = state != last_health_.state || fault != last_health_.fault ||
                       !(pub_.health_in == last_health_.runtime) ||
                       c.telemetry_drops != last_health_.drops ||
                       c.write_errors != last_health_.write_errors;
  const bool due = static_cast<double>(now - last_health_.ns) * 1e-9 >= config_.health_period_s;
  if (!force && !changed && !due) return;
  const HealthSample h =
      to_health(++last_health_.seq, pub_.have_newest ? &pub_.newest : nullptr, c, pub_.health_in);
  if (dds_write(dds_->health, &h) < 0) {
    published_.write_errors.fetch_add(1, std::memory_order_relaxed);
  } else {
    published_.health.fetch_add(1, std::memory_order_relaxed);
  }
  if (dds_->ros_diagnostics > 0) {
    const Ros2Diagnostics d = ros2_diagnostics(h, model_);
    const RosDiagnosticArray a = diagnostics_message(d, pub_.ros_diagnostics_storage);
    if (dds_write(dds_->ros_diagnostics, &a) < 0)
      published_.write_errors.fetch_add(1, std::memory_order_relaxed);
  }
  last_health_.ns = now;
  last_health_.state = state;
  last_health_.fault = fault;
  last_health_.runtime = pub_.health_in;
  last_health_.drops = c.telemetry_drops;
  last_health_.write_errors = c.write_errors;
}

}  // namespace zerog::telemetry
