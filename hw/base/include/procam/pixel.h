/* SPDX-License-Identifier: MIT
 * procam's bottom layer: the pixel types and the non-owning image view that
 * every layer shares (hw core, simulated rig, device backends, plugin ABI).
 *
 * Plain C so the plugin ABI (procam/plugin_abi.h) can include it; it depends
 * on nothing but the C standard headers, and nothing in it may ever depend on
 * a layer above. Layout and meaning are part of the plugin ABI: change only by
 * appending, with a PROCAM_PLUGIN_ABI_VERSION bump (see plugin_abi.h).
 */
#ifndef PROCAM_PIXEL_H
#define PROCAM_PIXEL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Pixel storage. Integer data carries `bit_depth` significant bits
 * (8, 10, 12, 14 or 16), right-aligned: a 12-bit frame in U16 ranges 0..4095. */
typedef enum procam_pixel_type {
  PROCAM_PIXEL_U8 = 1,
  PROCAM_PIXEL_U16 = 2,
  PROCAM_PIXEL_F32 = 3
} procam_pixel_type;

/* A view of an image; never owns its pixels. Row r starts at
 * (const uint8_t*)data + r * stride_bytes. Channels are interleaved. */
typedef struct procam_image {
  uint32_t width;
  uint32_t height;
  uint32_t channels;      /* 1 = grey */
  uint32_t pixel_type;    /* procam_pixel_type */
  uint32_t bit_depth;     /* significant bits of integer data; 32 for F32 */
  uint32_t reserved;
  size_t stride_bytes;
  const void* data;
} procam_image;

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* PROCAM_PIXEL_H */
