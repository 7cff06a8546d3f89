// ms_link_pkg: constants and the CRC-32 step shared by the host-link modules (rtl/link/).
// CRC-32/ISO-HDLC (zlib crc32; docs/protocol.md section 2): reflected polynomial 0xEDB88320,
// register initialised to 0xFFFFFFFF, result = register ^ 0xFFFFFFFF. Running the register
// over a packet followed by its own CRC (little-endian) leaves CRC32_RESIDUE.
package ms_link_pkg;
  localparam logic [31:0] CRC32_INIT    = 32'hFFFF_FFFF;
  localparam logic [31:0] CRC32_RESIDUE = 32'hDEBB_20E3;
  localparam int          HEADER_BYTES  = ms_protocol_pkg::HEADER_SIZE;
  localparam int          MAX_PAYLOAD   = ms_protocol_pkg::MAX_PAYLOAD;

  // one byte into the CRC register (8 shift steps, unrolled: ~3 LUT levels per bit)
  function automatic logic [31:0] crc32_byte(logic [31:0] crc, logic [7:0] data);
    logic [31:0] c;
    c = crc ^ {24'd0, data};
    for (int i = 0; i < 8; i++) c = c[0] ? ((c >> 1) ^ 32'hEDB8_8320) : (c >> 1);
    return c;
  endfunction
endpackage
