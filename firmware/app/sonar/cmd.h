/* Commands (docs/protocol.md sections 3, 4): cmd.c takes a transfer, checks it in the order of
 * section 4 and calls the opcode's handler from cmd_handlers[] (cmd_handlers.c), which fills the
 * reply payload in place; cmd.c then sends exactly one reply packet. */
#ifndef SONAR_CMD_H
#define SONAR_CMD_H

#include "app.h"


/* one buffer for the command and its reply: every handler reads payload word i before it
 * writes reply word i (same offset, 3), and the reply header is written last */
extern uint32_t cbuf[CMD_WORDS];
#define rbuf cbuf

/* pl: the payload (len bytes); writes the reply payload to rbuf[3..] and its byte count to
 * *rlen; returns the status */
typedef uint32_t (*cmd_fn)(const uint32_t *pl, uint32_t len, uint32_t *rlen);
typedef struct {
    cmd_fn fn;
    uint8_t payload; /* 0: a payload is BAD_LENGTH */
} cmd_handler_t;
extern const cmd_handler_t cmd_handlers[MS_OP_COUNT];

#endif
