#pragma once
// XDMF 3 pieces shared by the particle, wall and FEM outputs: one spelling of a DataItem that
// points into an HDF5 file, and escaping of user names (walls, materials) put into XML.

#include <cstdio>
#include <string>

namespace demfem::io {

/// `<DataItem ...>file:/dataset</DataItem>` of 8-byte numbers; `number_type` "Float" or "Int",
/// `dims` the dataset's dimensions separated by spaces ("n 3"), `ref` "file.h5:/dataset".
inline std::string xdmf_hdf_item(const std::string& dims, const char* number_type,
                                 const std::string& ref) {
  return "<DataItem Dimensions=\"" + dims + "\" NumberType=\"" + number_type +
         "\" Precision=\"8\" Format=\"HDF\">" + ref + "</DataItem>";
}

/// The file of output k of a series: "<stem>_NNNNNN.h5" (k zero-padded to six digits), the
/// one naming of the particle, wall and FEM snapshots that their XDMF indexes point to.
inline std::string series_file_name(const std::string& stem, std::size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "_%06zu.h5", k);
  return stem + buf;
}

/// Text as an XML attribute value or element text (&, <, >, " and ' escaped).
inline std::string xml_escape(const std::string& s) {
  std::string r;
  r.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        r += "&amp;";
        break;
      case '<':
        r += "&lt;";
        break;
      case '>':
        r += "&gt;";
        break;
      case '"':
        r += "&quot;";
        break;
      case '\'':
        r += "&apos;";
        break;
      default:
        r += c;
    }
  }
  return r;
}

}  // namespace demfem::io
