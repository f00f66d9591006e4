# Installed with the ament package: downstream packages that find_package(contextros_cpp)
# get contextros_add_layers() too.
include("${contextros_cpp_DIR}/ContextrosLayers.cmake")
