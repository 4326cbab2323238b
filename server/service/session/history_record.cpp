#include "service/session/history_record.h"

#include "service/session/convert.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>

#include <stdexcept>
#include <unordered_map>

namespace hdeform::service {

namespace st = ::hdeform::state;

namespace {

// Deterministic bytes: equal messages give equal keys for sharing values.
std::string bytes_of(const google::protobuf::MessageLite& m) {
  std::string out;
  google::protobuf::io::StringOutputStream stream(&out);
  google::protobuf::io::CodedOutputStream coded(&stream);
  coded.SetSerializationDeterministic(true);
  m.SerializeToCodedStream(&coded);
  coded.Trim();
  return out;
}

// Each shared value stored once: the index + 1 of a pointer already written.
class ValueWriter {
 public:
  explicit ValueWriter(st::StoredHistory& out) : out_(out) {}
  template <class T, class Set>
  std::uint32_t add(const std::shared_ptr<const T>& value, Set set) {
    if (!value) return 0;
    auto [it, inserted] = index_.emplace(value.get(), 0);
    if (inserted) {
      set(out_.add_values(), *value);
      it->second = static_cast<std::uint32_t>(out_.values_size());
    }
    return it->second;
  }

 private:
  st::StoredHistory& out_;
  std::unordered_map<const void*, std::uint32_t> index_;
};

void write_side(const Step& step, const EditState& side, ValueWriter& values,
                st::StoredEditState* out) {
  out->set_cs_key(side.cs_key);
  for (const auto& t : side.transforms) to_proto(t, out->add_transforms());
  if (step.constraints)
    out->set_given(values.add(side.given, [](st::StoredValue* v, const pb::Constraints& c) {
      *v->mutable_constraints() = c;
    }));
  if (step.beta) beta_to_proto(side.beta, out->mutable_beta());
  if (step.timeline)
    out->set_timeline(values.add(side.timeline, [](st::StoredValue* v, const pb::Timeline& t) {
      *v->mutable_timeline() = t;
    }));
  if (!step.snapshot.empty())
    out->set_snapshot(values.add(side.snapshot, [](st::StoredValue* v, const pb::NamedSnapshot& s) {
      *v->mutable_snapshot() = s;
    }));
}

// The stored values as shared objects; a value equal to one the session holds is that one.
class ValueReader {
 public:
  ValueReader(const st::StoredHistory& record, const HistoryContext& context) : record_(record) {
    if (context.current.given) known_.emplace(bytes_of(*context.current.given), context.current.given);
    if (context.current.timeline)
      known_.emplace(bytes_of(*context.current.timeline), context.current.timeline);
    for (const auto& [name, snap] : context.snapshots)
      if (snap) known_.emplace(bytes_of(*snap), snap);
    shared_.resize(static_cast<std::size_t>(record.values_size()));
  }

  template <class T>
  std::shared_ptr<const T> get(std::uint32_t ref, st::StoredValue::ValueCase kind, const T& (st::StoredValue::*field)() const,
                               const char* what) {
    if (ref == 0) return nullptr;
    if (ref > static_cast<std::uint32_t>(record_.values_size()))
      throw std::runtime_error(std::string(what) + " reference " + std::to_string(ref) +
                               " is out of range");
    const st::StoredValue& v = record_.values(static_cast<int>(ref - 1));
    if (v.value_case() != kind)
      throw std::runtime_error(std::string(what) + " reference " + std::to_string(ref) +
                               " names another kind of value");
    auto& slot = shared_[ref - 1];
    if (!slot) {
      const T& message = (v.*field)();
      auto it = known_.find(bytes_of(message));
      if (it != known_.end()) slot = it->second;
      else slot = std::make_shared<const T>(message);
    }
    return std::static_pointer_cast<const T>(slot);
  }

 private:
  const st::StoredHistory& record_;
  std::unordered_map<std::string, std::shared_ptr<const void>> known_;
  std::vector<std::shared_ptr<const void>> shared_;
};

EditState read_side(const Step& step, const st::StoredEditState& in, ValueReader& values,
                    const HistoryContext& context,
                    std::unordered_map<std::string, SessionBeta>& betas) {
  EditState out;
  out.cs_key = in.cs_key();
  out.transforms.reserve(static_cast<std::size_t>(in.transforms_size()));
  // Canonical forms (to_proto) carry their pivot, so no default pivot is ever used.
  for (const auto& t : in.transforms()) out.transforms.push_back(from_proto(t, Eigen::Vector3d::Zero()));
  if (step.constraints)
    out.given = values.get(in.given(), st::StoredValue::kConstraints, &st::StoredValue::constraints,
                           "constraints");
  if (step.beta) {
    // Local entries are resolved on the mesh once per distinct β, not once per step.
    const std::string key = bytes_of(in.beta());
    auto it = betas.find(key);
    if (it == betas.end()) {
      pb::Beta current;
      beta_to_proto(context.current.beta, &current);
      it = betas.emplace(key, bytes_of(current) == key ? context.current.beta
                                                       : context.parse_beta(in.beta()))
               .first;
    }
    out.beta = it->second;
  }
  if (step.timeline)
    out.timeline = values.get(in.timeline(), st::StoredValue::kTimeline, &st::StoredValue::timeline,
                              "timeline");
  if (!step.snapshot.empty())
    out.snapshot = values.get(in.snapshot(), st::StoredValue::kSnapshot, &st::StoredValue::snapshot,
                              "snapshot");
  return out;
}

}  // namespace

st::StoredHistory history_to_record(const History& history) {
  st::StoredHistory out;
  out.set_format(kHistoryFormat);
  out.set_next_id(history.next_id());
  ValueWriter values(out);
  for (const Step& s : history.steps()) {
    st::StoredStep* step = out.add_steps();
    *step->mutable_info() = s.info;
    step->set_constraints(s.constraints);
    step->set_beta(s.beta);
    step->mutable_handles()->Assign(s.handles.begin(), s.handles.end());
    step->set_timeline(s.timeline);
    step->set_snapshot(s.snapshot);
    write_side(s, s.before, values, step->mutable_before());
    write_side(s, s.after, values, step->mutable_after());
  }
  for (const auto& [client, ids] : history.redo_lists())
    (*out.mutable_redo())[client].mutable_ids()->Assign(ids.begin(), ids.end());
  return out;
}

void history_from_record(const st::StoredHistory& record, const HistoryContext& context,
                         History& history) {
  if (record.format() != kHistoryFormat)
    throw std::runtime_error("stored history has format " + std::to_string(record.format()) +
                             ", this server reads " + std::to_string(kHistoryFormat));
  ValueReader values(record, context);
  std::unordered_map<std::string, SessionBeta> betas;
  std::deque<Step> steps;
  std::int64_t last_id = 0;
  for (const auto& in : record.steps()) {
    Step s;
    s.info = in.info();
    if (s.info.id() <= last_id)
      throw std::runtime_error("stored history: step ids are not increasing at " +
                               std::to_string(s.info.id()));
    last_id = s.info.id();
    s.constraints = in.constraints();
    s.beta = in.beta();
    s.handles.assign(in.handles().begin(), in.handles().end());
    s.timeline = in.timeline();
    s.snapshot = in.snapshot();
    s.before = read_side(s, in.before(), values, context, betas);
    s.after = read_side(s, in.after(), values, context, betas);
    // A constraints side is what Undo makes the session's constraints: they and one transform
    // per handle, or none of either (before the first constraints).
    if (s.constraints)
      for (const EditState* side : {&s.before, &s.after}) {
        const std::size_t handles = side->given ? static_cast<std::size_t>(side->given->handles_size()) : 0;
        if (side->cs_key.empty() != !side->given || side->transforms.size() != handles)
          throw std::runtime_error("stored history: step " + std::to_string(s.info.id()) +
                                   " has constraints without their transforms, or the reverse");
      }
    // A constraints step replaces every transform (its `before` may have none).
    for (const EditState* side : {&s.before, &s.after})
      for (int h : s.constraints ? std::vector<int>{} : s.handles)
        if (h < 0 || static_cast<std::size_t>(h) >= side->transforms.size())
          throw std::runtime_error("stored history: step " + std::to_string(s.info.id()) +
                                   " names handle " + std::to_string(h) + " it has no transform for");
    steps.push_back(std::move(s));
  }
  std::map<std::string, std::vector<std::int64_t>> redo;
  for (const auto& [client, ids] : record.redo())
    redo[client].assign(ids.ids().begin(), ids.ids().end());
  history.adopt(std::move(steps), record.next_id(), std::move(redo));
}

}  // namespace hdeform::service
