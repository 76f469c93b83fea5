/// \file broadphase.hpp
/// Everything of the library in one include: the vocabulary, the interface,
/// the registry of structures by name, scenes and replay.
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/handle.hpp>
#include <broadphase/naive.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/structure.hpp>
