// The element order of an OSM XML file, as GDAL's OSM driver needs it.
//
// GDAL's OSM driver reads a file once, front to back. With its default node
// index (OSM_USE_CUSTOM_INDEXING=YES) it stops at the first node id that does
// not increase ("Non increasing node id"), which Overpass API output
// (`out qt`, quadtile order) triggers; the plain index takes any order. In
// either mode a way is assembled only from nodes read before it, so a file
// listing ways before their nodes (Overpass `out; >; out skel qt;`) loses its
// ways and multipolygons without an error. One pass over the bytes finds both
// before GDAL parses the file.
#pragma once

#include <cstdint>
#include <string>

namespace prep::detail {

struct OsmXmlOrder {
  bool scanned = false;           // an uncompressed OSM XML file, read to its end
  bool node_ids_increase = true;  // every <node> id greater than the one before
  // The first <node> after a <way> or <relation> (late_node_offset < 0: none).
  int64_t late_node_offset = -1;  // byte offset of that <node
  std::string late_node_id;
  std::string earlier_kind, earlier_id;  // the first way or relation before it
};

// Scans `path` (any GDAL virtual path) when it is OSM XML: its first element
// (after a UTF-8 BOM, the XML declaration and comments) is <osm>. Anything
// else (OSM PBF, GML or other XML, compressed or unreadable files) returns
// scanned == false after reading at most 64 KiB.
OsmXmlOrder scan_osm_xml(const std::string& path);

}  // namespace prep::detail
