// The ROS-free C++ COP runtime of ContextROS: layers, activation, layered functions.
#pragma once

#include "contextros/activation.hpp"
#include "contextros/errors.hpp"
#include "contextros/layer.hpp"
#include "contextros/layered.hpp"
