// demfem_h5_compare A.h5 B.h5 [--skip TEXT]... [--list]: are two HDF5 files the same data,
// bit for bit? Every group, dataset and attribute (on the root, on groups and on datasets) of
// both files, by name: the same names on both sides, and for each dataset and attribute the
// same type, the same shape and the same bytes (variable-length strings: the same strings).
// The files themselves are not compared: HDF5 stores object modification times and free
// space, so two runs that computed the same numbers write different file bytes.
//
// Objects and attributes whose path (/group/dataset, or /object@attribute) contains a --skip
// TEXT are left out (e.g. a checkpoint's wall-time sums). --list prints the paths compared.
// Exit status: 0 equal, 1 different (each difference on stdout, one a line), 2 bad input (a
// file that is missing or not HDF5, a type this tool cannot read).
//
// Used by tools/sleeper_kill_run.py (issue 15: a killed and recovered run against the
// uninterrupted one).
#include <hdf5.h>

#include <cstdio>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

struct BadInput : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// One dataset's or attribute's value: its type (as text), shape and bytes.
struct Value {
  std::string type;
  std::vector<hsize_t> shape;
  std::vector<unsigned char> bytes;  // fixed-size types
  std::vector<std::string> strings;  // variable-length strings
  bool operator==(const Value& o) const = default;
};

std::string type_text(hid_t type) {
  // Class, size, sign/order are what decide equal bits; the full text form (H5LT) is in the
  // high-level library, which is not needed for that.
  const H5T_class_t c = H5Tget_class(type);
  std::string t =
      "class " + std::to_string(static_cast<int>(c)) + " size " + std::to_string(H5Tget_size(type));
  if (c == H5T_INTEGER) t += " sign " + std::to_string(static_cast<int>(H5Tget_sign(type)));
  if (c == H5T_INTEGER || c == H5T_FLOAT)
    t += " order " + std::to_string(static_cast<int>(H5Tget_order(type)));
  if (c == H5T_STRING && H5Tis_variable_str(type) > 0) t += " variable";
  return t;
}

std::vector<hsize_t> shape_of(hid_t space) {
  const int rank = H5Sget_simple_extent_ndims(space);
  std::vector<hsize_t> dims(rank > 0 ? rank : 0);
  if (rank > 0) H5Sget_simple_extent_dims(space, dims.data(), nullptr);
  return dims;
}

hsize_t count_of(const std::vector<hsize_t>& shape) {
  hsize_t n = 1;
  for (hsize_t d : shape) n *= d;
  return n;
}

// Reads a dataset (is_attribute false) or an attribute into a Value.
Value read_value(hid_t id, bool is_attribute, const std::string& where) {
  Value v;
  const hid_t type = is_attribute ? H5Aget_type(id) : H5Dget_type(id);
  const hid_t space = is_attribute ? H5Aget_space(id) : H5Dget_space(id);
  if (type < 0 || space < 0) throw BadInput(where + ": cannot read its type or shape");
  v.type = type_text(type);
  v.shape = shape_of(space);
  const hsize_t n = H5Sget_simple_extent_type(space) == H5S_NULL ? 0 : count_of(v.shape);
  const H5T_class_t c = H5Tget_class(type);
  herr_t status = 0;
  if (c == H5T_STRING && H5Tis_variable_str(type) > 0) {
    std::vector<char*> p(n, nullptr);
    if (n > 0) {
      status = is_attribute ? H5Aread(id, type, p.data())
                            : H5Dread(id, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, p.data());
      for (char* s : p) v.strings.emplace_back(s ? s : "");
      if (status >= 0) H5Dvlen_reclaim(type, space, H5P_DEFAULT, p.data());
    }
  } else if (c == H5T_VLEN || c == H5T_REFERENCE ||
             (c == H5T_COMPOUND && H5Tdetect_class(type, H5T_VLEN) > 0)) {
    H5Tclose(type);
    H5Sclose(space);
    throw BadInput(where + ": a variable-length or reference type (not supported)");
  } else {
    v.bytes.resize(n * H5Tget_size(type));
    if (n > 0)
      status = is_attribute ? H5Aread(id, type, v.bytes.data())
                            : H5Dread(id, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.bytes.data());
  }
  H5Tclose(type);
  H5Sclose(space);
  if (status < 0) throw BadInput(where + ": cannot read its data");
  return v;
}

struct Contents {
  std::map<std::string, std::string> kinds;  // path -> "group" / "dataset" / "attribute"
  std::map<std::string, Value> values;       // datasets and attributes
};

struct VisitState {
  hid_t file;
  Contents* out;
  const std::vector<std::string>* skip;
  std::string file_name;
  std::string error;
};

bool skipped(const std::string& path, const std::vector<std::string>& skip) {
  for (const auto& s : skip)
    if (path.find(s) != std::string::npos) return true;
  return false;
}

herr_t collect_attribute(hid_t object, const char* name, const H5A_info_t*, void* data) {
  auto* st = static_cast<std::pair<VisitState*, std::string>*>(data);
  const std::string path = st->second + "@" + name;
  if (skipped(path, *st->first->skip)) return 0;
  const hid_t a = H5Aopen(object, name, H5P_DEFAULT);
  if (a < 0) {
    st->first->error = st->first->file_name + ": " + path + ": cannot open the attribute";
    return -1;
  }
  try {
    st->first->out->values[path] = read_value(a, true, st->first->file_name + ": " + path);
  } catch (const BadInput& e) {
    st->first->error = e.what();
    H5Aclose(a);
    return -1;
  }
  H5Aclose(a);
  st->first->out->kinds[path] = "attribute";
  return 0;
}

bool collect_object(VisitState& st, const std::string& path) {
  if (skipped(path, *st.skip)) return true;
  const hid_t o = H5Oopen(st.file, path.c_str(), H5P_DEFAULT);
  if (o < 0) {
    st.error = st.file_name + ": " + path + ": cannot open it";
    return false;
  }
  const H5I_type_t t = H5Iget_type(o);
  bool ok = true;
  if (t == H5I_DATASET) {
    st.out->kinds[path] = "dataset";
    try {
      st.out->values[path] = read_value(o, false, st.file_name + ": " + path);
    } catch (const BadInput& e) {
      st.error = e.what();
      ok = false;
    }
  } else {
    st.out->kinds[path] = t == H5I_GROUP ? "group" : "other";
  }
  if (ok) {
    std::pair<VisitState*, std::string> a{&st, path};
    hsize_t idx = 0;
    if (H5Aiterate2(o, H5_INDEX_NAME, H5_ITER_INC, &idx, collect_attribute, &a) < 0) ok = false;
  }
  H5Oclose(o);
  return ok;
}

herr_t visit_link(hid_t, const char* name, const H5L_info_t* info, void* data) {
  auto* st = static_cast<VisitState*>(data);
  std::string path = "/";
  path += name;
  if (info->type != H5L_TYPE_HARD) {
    st->out->kinds[path] = "link";
    return 0;
  }
  return collect_object(*st, path) ? 0 : -1;
}

Contents read_file(const std::string& file, const std::vector<std::string>& skip) {
  if (H5Fis_hdf5(file.c_str()) <= 0) throw BadInput(file + ": missing or not an HDF5 file");
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) throw BadInput(file + ": cannot open it");
  Contents c;
  VisitState st{f, &c, &skip, file, {}};
  bool ok = collect_object(st, "/");
  if (ok) ok = H5Lvisit(f, H5_INDEX_NAME, H5_ITER_INC, visit_link, &st) >= 0;
  H5Fclose(f);
  if (!ok) throw BadInput(st.error.empty() ? file + ": cannot walk its objects" : st.error);
  return c;
}

std::string shape_text(const std::vector<hsize_t>& s) {
  std::string t = "[";
  for (std::size_t i = 0; i < s.size(); ++i)
    t += (i ? " x " : "") + std::to_string(static_cast<unsigned long long>(s[i]));
  return t + "]";
}

// How two values differ, in words (the first differing element of a numeric array).
std::string difference(const Value& a, const Value& b) {
  if (a.type != b.type) return "type " + a.type + " against " + b.type;
  if (a.shape != b.shape) return "shape " + shape_text(a.shape) + " against " + shape_text(b.shape);
  if (a.strings != b.strings) return "strings differ";
  const std::size_t n = a.bytes.size();
  const bool is_double = a.type.rfind("class 1 size 8", 0) == 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (a.bytes[i] == b.bytes[i]) continue;
    if (is_double) {
      const std::size_t k = i / 8;
      double x, y;
      std::memcpy(&x, &a.bytes[k * 8], 8);
      std::memcpy(&y, &b.bytes[k * 8], 8);
      char text[128];
      std::snprintf(text, sizeof text, "element %zu: %.17g against %.17g", k, x, y);
      return text;
    }
    return "byte " + std::to_string(i) + " differs";
  }
  return "differs";
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> files, skip;
  bool list = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--skip" && i + 1 < argc) {
      skip.emplace_back(argv[++i]);
    } else if (a == "--list") {
      list = true;
    } else if (a.rfind("--", 0) == 0) {
      std::fprintf(stderr, "demfem_h5_compare: unknown option %s\n", a.c_str());
      return 2;
    } else {
      files.push_back(a);
    }
  }
  if (files.size() != 2) {
    std::fprintf(stderr, "usage: demfem_h5_compare A.h5 B.h5 [--skip TEXT]... [--list]\n");
    return 2;
  }
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // our own messages name the file and object
  Contents a, b;
  try {
    a = read_file(files[0], skip);
    b = read_file(files[1], skip);
  } catch (const BadInput& e) {
    std::fprintf(stderr, "demfem_h5_compare: %s\n", e.what());
    return 2;
  }
  int differences = 0;
  for (const auto& [path, kind] : a.kinds) {
    if (list) std::printf("%s %s\n", kind.c_str(), path.c_str());
    const auto it = b.kinds.find(path);
    if (it == b.kinds.end()) {
      std::printf("%s %s: only in %s\n", kind.c_str(), path.c_str(), files[0].c_str());
      ++differences;
    } else if (it->second != kind) {
      std::printf("%s: a %s against a %s\n", path.c_str(), kind.c_str(), it->second.c_str());
      ++differences;
    } else if (const auto va = a.values.find(path); va != a.values.end()) {
      const Value& vb = b.values.at(path);
      if (!(va->second == vb)) {
        std::printf("%s %s: %s\n", kind.c_str(), path.c_str(), difference(va->second, vb).c_str());
        ++differences;
      }
    }
  }
  for (const auto& [path, kind] : b.kinds)
    if (!a.kinds.count(path)) {
      std::printf("%s %s: only in %s\n", kind.c_str(), path.c_str(), files[1].c_str());
      ++differences;
    }
  if (differences == 0 && list) std::printf("equal: %zu objects and attributes\n", a.kinds.size());
  return differences == 0 ? 0 : 1;
}
