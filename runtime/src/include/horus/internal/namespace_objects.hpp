// A namespace's shared-memory objects besides its topic segments: the log ring that `horus log`
// reads (<root>/@logs/<namespace>, runtime/src/scheduler/log_ring.cpp), the presence folder
// that `horus node list` reads (<root>/@presence/<namespace>, runtime/src/presence/), the
// parameter stores (<root>/@params/<namespace>/<node>, runtime/src/params/) and the frame tree
// (<root>/@frames/<namespace>, runtime/src/frames/). The transport's clean_namespace() and
// remove_namespace() reach them through these functions.
//
// Who uses them is told by flock(2), which the kernel drops when a process dies: every process
// that writes the ring holds a shared lock on it for as long as its mapping lives, and every
// Scheduler holds a shared lock on its presence folder for as long as it announces there. A
// cleaner takes the exclusive lock without waiting, so it removes only what no live process uses;
// an opener re-checks, once locked, that what it opened is still linked, and starts over if a
// cleaner removed it in between. The frame tree does the same with an OFD lock (fcntl), its flock
// being its writers' own.
#pragma once

#include <optional>
#include <string_view>
#include <vector>

#include "horus/topic_registry.hpp"

namespace horus::detail {

/// The namespace's log ring (empty: the current namespace), or nothing when it has none.
std::optional<NamespaceObjectInfo> log_ring_object(std::string_view namespace_name);
/// Unlinks the namespace's log ring when no live process writes it (`force`: even when one
/// does; its lines then go to memory nobody else sees). Whether it was removed.
bool remove_log_ring(std::string_view namespace_name, bool force);

/// The namespace's presence folder, or nothing when it has none.
std::optional<NamespaceObjectInfo> presence_folder_object(std::string_view namespace_name);
/// Removes the namespace's presence folder when it is empty and no live Scheduler announces
/// there (`force`: with whatever it holds, announcers or not). Whether it was removed.
bool remove_presence_folder(std::string_view namespace_name, bool force);

/// The namespace's parameter stores (<root>/@params/<namespace>/<node>, runtime/src/params/),
/// one entry each; in use while their owner runs (it holds the store's flock exclusively).
std::vector<NamespaceObjectInfo> param_store_objects(std::string_view namespace_name);
/// Unlinks the namespace's parameter stores that no live owner holds (`force`: all), and their
/// folder once empty. How many went.
std::size_t remove_param_stores(std::string_view namespace_name, bool force);

/// The namespace's frame tree (<root>/@frames/<namespace>, runtime/src/frames/), its size being
/// the memory it holds; in use while any process has it open (each holds a shared OFD lock).
std::optional<NamespaceObjectInfo> frame_tree_object(std::string_view namespace_name);
/// Unlinks the namespace's frame tree when no process has it open, static frames and all.
/// Whether it was removed.
bool remove_unused_frame_tree(std::string_view namespace_name);

}  // namespace horus::detail
