/* rd_internal.h: TEMPORARY umbrella while renderer/ moves to per-subsystem headers. */
#ifndef RD_INTERNAL_H
#define RD_INTERNAL_H
#include "core/rd_core.h"
#include "media/rd_freepath.h"
#include "scene/rd_scene.h"
#include "transport/rd_path.h"
#endif
