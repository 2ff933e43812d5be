# Embeds one OpenCL C (or shared C) source as a C++ string constant. The text starts with a
# #line directive naming the real file, so compiler logs point at it.
# Inputs: SOURCE (absolute path), OUTPUT (.cpp to write), SYMBOL (C++ identifier).
file(READ "${SOURCE}" body)
set(delim "VFCL_EMBED")
string(FIND "${body}" ")${delim}\"" clash)
if(NOT clash EQUAL -1)
  message(FATAL_ERROR "${SOURCE} contains the raw-string delimiter )${delim}\"")
endif()
file(WRITE "${OUTPUT}.tmp"
  "// Generated from ${SOURCE} by embed_kernel.cmake; do not edit.\n"
  "namespace voxfield::cl_sources {\n"
  "extern const char* const ${SYMBOL};\n"
  "const char* const ${SYMBOL} = R\"${delim}(#line 1 \"${SOURCE}\"\n${body})${delim}\";\n"
  "}\n")
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
