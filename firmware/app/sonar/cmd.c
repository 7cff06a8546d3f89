/* The command transport: a complete bulk OUT transfer shows in CMD_STATUS (size, CRC verdict
 * computed by the link); its words are read from CMD_DATA, checked in the order of
 * docs/protocol.md section 4, passed to the opcode's handler (cmd_handlers[]) and answered with
 * exactly one reply packet written to REPLY_TX (header + payload; the link appends the CRC-32
 * and sends it ahead of queued frames). */
#include "cmd.h"

uint32_t cbuf[CMD_WORDS];

/* one reply packet: header + len payload bytes from rbuf[3..] (the link appends the CRC) */
static void reply(uint32_t type, uint32_t status, uint32_t seq, uint32_t len)
{
    if (status != MS_ST_OK)
        bad_commands++;
    rbuf[0] = MS_MAGIC_REPLY | (MS_PROTOCOL_VERSION << 16) | (type << 24);
    rbuf[1] = (status << 8) | (len << 16);
    rbuf[2] = seq;
    uint32_t n = (MS_HEADER_SIZE + len + 3u) / 4u;
    for (uint32_t i = 0; i < n; i++)
        MS_SOC(REPLY_TX) = rbuf[i];
    MS_SOC(HOST_CTRL) = SOC_REGS__HOST_CTRL__REPLY_END_bm;
}

/* the header's verdict (section 4 order); MS_ST_OK: the handler runs */
static uint32_t check(uint32_t n, uint32_t cs, uint32_t op, uint32_t len)
{
    if (len > MS_MAX_PAYLOAD || n != MS_HEADER_SIZE + MS_CRC_SIZE + len
        || (cs & SOC_REGS__CMD_STATUS__OVERLONG_bm))
        return MS_ST_BAD_LENGTH;
    if (!(cs & SOC_REGS__CMD_STATUS__CRC_OK_bm))
        return MS_ST_BAD_CRC;
    if (op < MS_OP_DEVICE_INFO || op >= MS_OP_COUNT || !cmd_handlers[op].fn)
        return MS_ST_UNKNOWN_OPCODE;
    if (!cmd_handlers[op].payload && len != 0u)
        return MS_ST_BAD_LENGTH;
    return MS_ST_OK;
}

/* one complete command transfer from the link -> exactly one reply */
void handle_command(void)
{
    uint32_t t = now32();
    uint32_t cs = MS_SOC(CMD_STATUS);
    uint32_t n = (cs & SOC_REGS__CMD_STATUS__BYTES_bm) >> SOC_REGS__CMD_STATUS__BYTES_bp;
    uint32_t nw = (n + 3u) / 4u;
    if (nw > CMD_WORDS)
        nw = CMD_WORDS;
    for (uint32_t i = 0; i < nw; i++)
        cbuf[i] = MS_SOC(CMD_DATA);
    MS_SOC(HOST_CTRL) = SOC_REGS__HOST_CTRL__CMD_NEXT_bm;

    uint32_t magic = cbuf[0] & 0xFFFFu, ver = (cbuf[0] >> 16) & 0xFFu, op = cbuf[0] >> 24;
    uint32_t len = cbuf[1] >> 16, seq = cbuf[2], rop = (op | MS_REPLY_BIT) & 0xFFu;
    uint32_t st, rlen = 0;
    if (n < MS_HEADER_SIZE + MS_CRC_SIZE) {
        reply(MS_ERROR_REPLY_TYPE, MS_ST_BAD_LENGTH, 0u, 0u);
        return;
    }
    if (magic != MS_MAGIC_COMMAND) {
        reply(MS_ERROR_REPLY_TYPE, MS_ST_BAD_MAGIC, seq, 0u);
        return;
    }
    if (ver != MS_PROTOCOL_VERSION) {
        rbuf[3] = MS_PROTOCOL_VERSION;
        reply(MS_ERROR_REPLY_TYPE, MS_ST_BAD_VERSION, seq, 1u);
        return;
    }
    st = check(n, cs, op, len);
    if (st == MS_ST_OK)
        st = cmd_handlers[op].fn(&cbuf[3], len, &rlen);
    reply(rop, st, seq, rlen);
    uint32_t dt = now32() - t;
    if (op != MS_OP_START && op != MS_OP_STOP) /* not slices of a running table: START prepares
                                           * every sensor first, STOP flushes at the end */
        stat_max(MS_FW_STAT_CYCLES_COMMAND_MAX, dt);
    ms_report(0x70000000u | (op << 20) | (st << 16) | (dt > 0xFFFFu ? 0xFFFFu : dt));
}
