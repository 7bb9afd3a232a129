// SurfMesh bindings — SurfaceMesh.optimize(): smoothing and untangling with a cancellable
// Python progress callback.
#include "arrays.h"
#include "handle.h"
#include "surfmesh/optimize/optimizer.h"

#include <pybind11/functional.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace surfmesh::bindings {

py::dict statsToDict(const QualityStats& s);

namespace {

/// One of optimize()'s options: its keyword name and the OptimizeOptions member it sets.
struct OptionField {
  const char* name;
  std::function<py::object(const OptimizeOptions&)> get;
  std::function<void(OptimizeOptions&, py::handle)> set;
};

template <class T>
OptionField field(const char* name, T OptimizeOptions::*member) {
  return {name, [member](const OptimizeOptions& o) { return py::cast(o.*member); },
          [member](OptimizeOptions& o, py::handle v) { o.*member = v.cast<T>(); }};
}

/// The options by their keyword names: the one list the defaults, the keywords and the
/// assignments come from.
const std::vector<OptionField>& optionFields() {
  static const std::vector<OptionField> fields = {
      field("measure", &OptimizeOptions::measure),
      field("max_sweeps", &OptimizeOptions::maxSweeps),
      field("rel_tol", &OptimizeOptions::relTol),
      field("move_tol", &OptimizeOptions::moveTol),
      field("inner_iterations", &OptimizeOptions::innerIterations),
      field("max_line_search", &OptimizeOptions::maxLineSearch),
      field("over_relaxation", &OptimizeOptions::overRelaxation),
      field("delta_policy", &OptimizeOptions::deltaPolicy),
      field("delta_epsilon", &OptimizeOptions::deltaEpsilon),
      field("delta", &OptimizeOptions::delta),
      field("monotone", &OptimizeOptions::monotone),
      field("threads", &OptimizeOptions::threads),
      field("high_order", &OptimizeOptions::highOrder),
      field("topology", &OptimizeOptions::topology),
  };
  return fields;
}

std::string optionNames() {
  std::string s;
  for (const OptionField& f : optionFields()) s += (s.empty() ? "" : ", ") + std::string(f.name);
  return s;
}

}  // namespace

void bind_optimize(MeshClass& cls) {
  // The one source of the options' defaults on the Python side (SurfMesh.app.options):
  // a default-constructed OptimizeOptions, by optimize()'s keyword names.
  cls.def_static(
      "optimize_defaults",
      []() {
        const OptimizeOptions o;
        py::dict d;
        for (const OptionField& f : optionFields()) d[f.name] = f.get(o);
        return d;
      },
      ("The defaults of optimize()'s options (the core's OptimizeOptions), by its keyword "
       "names: " +
       optionNames() + ".")
          .c_str());
  cls.def(
      "optimize",
      [](MeshHandle& h, py::kwargs kwargs) {
        OptimizeOptions o;
        py::object progress = py::none(), before = py::none(), fixed = py::none();
        for (auto item : kwargs) {
          const std::string key = py::cast<std::string>(item.first);
          if (key == "progress") {
            progress = py::reinterpret_borrow<py::object>(item.second);
            continue;
          }
          if (key == "before") {
            before = py::reinterpret_borrow<py::object>(item.second);
            continue;
          }
          if (key == "fixed") {
            fixed = py::reinterpret_borrow<py::object>(item.second);
            continue;
          }
          const auto& fields = optionFields();
          const auto it = std::find_if(fields.begin(), fields.end(),
                                       [&](const OptionField& f) { return key == f.name; });
          if (it == fields.end())
            throw py::type_error("optimize() got an unexpected keyword argument '" + key +
                                 "'; options: " + optionNames() + ", progress, before, fixed");
          try {
            it->set(o, item.second);
          } catch (const py::cast_error&) {
            throw py::type_error("optimize(): " + key + " has the wrong type (" +
                                 py::cast<std::string>(py::str(py::type::of(item.second))) + ")");
          }
        }
        o.fixedNodes = toMask(fixed, static_cast<py::ssize_t>(h.get().nodeCount()), "fixed");
        if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
          throw std::invalid_argument("progress must be callable or None");
        // The callback runs on the calling thread after each sweep (GIL released around the
        // sweeps): it takes the GIL, and a Python exception cancels the run and is re-raised.
        std::unique_ptr<py::error_already_set> pyError;
        ProgressCallback cb;
        if (!progress.is_none()) {
          cb = [&](const OptimizeProgress& p) -> bool {
            py::gil_scoped_acquire gil;
            try {
              py::dict d;
              d["sweep"] = p.sweep;
              d["max_sweeps"] = p.maxSweeps;
              d["objective"] = p.objective;
              d["tangled"] = p.tangled;
              d["min_quality"] = p.minQuality;
              d["delta"] = p.delta;
              d["stage"] = p.stage;
              py::object r = progress(d);
              return r.is_none() || r.cast<bool>();
            } catch (py::error_already_set& e) {
              pyError = std::make_unique<py::error_already_set>(std::move(e));
              return false;
            }
          };
        }
        SurfaceMesh& mesh = h.get();
        // The caller's measure of the mesh as it is (the "stats" of measure(measure)): not
        // measured again.
        QualityStats given;
        const bool haveBefore = !before.is_none();
        if (haveBefore) {
          const py::dict b = py::cast<py::dict>(before);
          given.min = b["min"].cast<double>();
          given.max = b["max"].cast<double>();
          given.mean = b["mean"].cast<double>();
          given.stddev = b["std"].cast<double>();
          given.tangled = b["tangled"].cast<std::size_t>();
          given.elements = b["elements"].cast<std::size_t>();
          if (b.contains("across")) given.across = b["across"].cast<std::size_t>();
          if (given.elements != mesh.elementCount())
            throw std::invalid_argument("before: stats of " + std::to_string(given.elements) +
                                        " elements for a mesh of " +
                                        std::to_string(mesh.elementCount()));
        }
        OptimizeResult r;
        {
          py::gil_scoped_release release;
          r = optimizeMesh(mesh, o, cb, haveBefore ? &given : nullptr);
        }
        if (pyError) throw std::move(*pyError);
        py::dict d;
        d["before"] = statsToDict(r.before);
        d["after"] = statsToDict(r.after);
        d["sweeps"] = r.sweeps;
        d["seconds"] = r.seconds;
        d["reason"] = std::string(stopReasonName(r.reason));
        d["initial_objective"] = r.initialObjective;
        d["final_objective"] = r.finalObjective;
        d["moved_nodes"] = r.movedNodes;
        d["threads"] = r.threadsUsed;
        d["patch_untanglings"] = r.patchUntanglings;
        d["straightened_elements"] = r.straightenedElements;
        d["tangled_unmovable"] = r.tangledUnmovable;
        d["tangled_movable"] = r.tangledMovable;
        d["flips"] = r.flips;
        d["rewired_elements"] = r.rewiredElements;
        d["needles"] = r.needles;
        d["restored_nodes"] = r.restoredNodes;
        d["warnings"] = r.warnings;
        return d;
      },
      "Optimizes the mesh in place (nodes stay on their surfaces). Keyword options (the "
      "core's OptimizeOptions, defaults: optimize_defaults()), progress, before, fixed. "
      "progress(dict) is called "
      "after every sweep; returning False cancels (reason 'cancelled', mesh unchanged). "
      "Returns a dict: before, after (stats), sweeps, seconds, reason, moved_nodes, threads, "
      "patch_untanglings (escapes of stuck tangled elements by joint relaxation tried), "
      "straightened_elements (tangled high-order triangles untangled by straight sides in "
      "(u,v)), "
      "tangled_unmovable / tangled_movable (ids of the elements left tangled without / with a "
      "movable node), flips, rewired_elements (ids of the elements whose node lists edge flips "
      "changed: element_nodes() gives them), needles (elements with every corner on one CAD "
      "edge, topology 'flip'), restored_nodes (nodes put back where they were because the run "
      "left invalid an element valid in the input) and warnings (a line for each non-empty "
      "list). before: the stats "
      "dict of "
      "measure(measure) on the mesh as it is, when the caller has it (not measured again). "
      "fixed: None or a bool per node, True for the nodes the run leaves where they are.");
}

}  // namespace surfmesh::bindings
