-- The dissectors: what follows is the same for every model; only GEN, above, is generated.
--
-- Three protocols, each checked as rcmlconf's own codecs check it (offsets, reasons and the
-- requirement broken), with an expert error at the bytes of every malformed part:
--   rctp     RCTP/2.0 control messages on TCP (D-RCTP-4): reassembled by Content-Length,
--            several to a segment, in both directions
--   rctpds   the RCTP/2.0 data stream on UDP (D-RCTP-19, D-RCTP-20, D-RCTP-22)
--   rcmlrsp  RSP on UDP (D-RSP-10, D-RSP-11, D-RSP-14): with a robot model, the Device Map and
--            every payload's fields ("rsp" is another protocol's name in Wireshark)

local C = GEN.rctp
local D = GEN.datastream
local R = GEN.rsp
local M = GEN.model

-- Helpers ------------------------------------------------------------------------------------

-- Big-endian numbers from a Lua string of the bytes, at offsets from 0. Every TvbRange costs an
-- allocation, and tshark reads millions of packets: numbers are read from `tvb:raw()` once, and a
-- TvbRange is made only for what goes into the tree.
local byte = string.byte

local function u8(raw, at)
    return byte(raw, at + 1)
end

local function u16(raw, at)
    local a, b = byte(raw, at + 1, at + 2)
    return a * 256 + b
end

local function describe(names, value)
    local name = names[value]
    if name ~= nil then
        return name
    end
    return "unknown (" .. tostring(value) .. ")"
end

local function plural(count, word)
    if count == 1 then
        return "1 " .. word
    end
    return tostring(count) .. " " .. word .. "s"
end

-- The members of an enum as "1 read, 2 write": what a byte that is none of them is told.
local function choices(names)
    local keys = {}
    for key in pairs(names) do
        keys[#keys + 1] = key
    end
    table.sort(keys)
    local parts = {}
    for _, key in ipairs(keys) do
        parts[#parts + 1] = tostring(key) .. " " .. names[key]
    end
    return table.concat(parts, ", ")
end

-- The bytes from `at`, `length` of them, or none at the end: a tree item's range.
local function span(tvb, at, length)
    local size = tvb:len()
    if at > size then
        at = size
    end
    if length < 0 or at + length > size then
        length = size - at
    end
    return tvb:range(at, length)
end

-- Malformed parts: an expert error at the bytes at fault, and the reason, the offset from the
-- start of the message or datagram and the requirement broken as fields (`PROTO.malformed`,
-- `PROTO.malformed.offset`, `PROTO.malformed.rule`), so that a filter finds them.
local function malformed_fields(abbr, what)
    local set = {
        reason = ProtoField.string(abbr .. ".malformed", "Malformed"),
        offset = ProtoField.uint32(abbr .. ".malformed.offset", "Offset of the fault"),
        rule = ProtoField.string(abbr .. ".malformed.rule", "Requirement broken"),
        expert = ProtoExpert.new(
            abbr .. ".malformed.expert", "Malformed " .. what, expert.group.MALFORMED,
            expert.severity.ERROR),
        warning = ProtoExpert.new(
            abbr .. ".warning", what .. ": well framed, but wrong", expert.group.PROTOCOL,
            expert.severity.WARN),
        note = ProtoExpert.new(
            abbr .. ".note", what .. ": note", expert.group.SEQUENCE, expert.severity.NOTE),
    }
    return set
end

-- `offset`, when given, is the offset told (the codec's), `at` still the bytes shown.
local function report(set, tree, tvb, at, length, base, reason, rule, offset)
    local label = reason
    if rule ~= nil then
        label = "[" .. rule .. "] " .. reason
    end
    local item = tree:add(set.reason, span(tvb, at, length), reason)
    item:set_text("Malformed: " .. label)
    item:add_proto_expert_info(set.expert, label)
    item:add(set.offset, offset or (at - base)):set_generated()
    if rule ~= nil then
        item:add(set.rule, rule):set_generated()
    end
    return item
end

local function warn(set, item, reason, rule)
    if rule ~= nil then
        reason = "[" .. rule .. "] " .. reason
    end
    item:add_proto_expert_info(set.warning, reason)
end

-- A bytes field over its bytes; an empty one says so (rather than Wireshark's "<MISSING>").
local function add_bytes(tree, field, tvb, at, length, label)
    local item = tree:add(field, tvb:range(at, length))
    if length == 0 then
        item:set_text(label .. ": (empty)")
    end
    return item
end

local function register_ports(table_name, proto, old, new)
    local ports = DissectorTable.get(table_name)
    if old ~= nil and old ~= "" then
        ports:remove(old, proto)
    end
    if new ~= nil and new ~= "" then
        ports:add(new, proto)
    end
end

-- RCTP/2.0 control (TCP) -----------------------------------------------------------------------

local rctp = Proto("rctp", "RCTP/2.0 control")
local CF = {
    method = ProtoField.string("rctp.method", "Method"),
    target = ProtoField.string("rctp.target", "Request target"),
    version = ProtoField.string("rctp.version", "Version"),
    status = ProtoField.uint16("rctp.status", "Status code", base.DEC, C.statuses),
    phrase = ProtoField.string("rctp.phrase", "Reason phrase"),
    header = ProtoField.string("rctp.header", "Header field"),
    cseq = ProtoField.uint32("rctp.cseq", "CSeq"),
    session = ProtoField.string("rctp.session", "Session"),
    session_id = ProtoField.string("rctp.session.id", "Session ID"),
    session_timeout = ProtoField.uint32("rctp.session.timeout", "Session timeout (s)"),
    content_length = ProtoField.uint32("rctp.content_length", "Content-Length"),
    content_type = ProtoField.string("rctp.content_type", "Content-Type"),
    nodes = ProtoField.string("rctp.nodes", "Nodes"),
    transport = ProtoField.string("rctp.transport", "Transport"),
    client_port = ProtoField.uint16("rctp.transport.client_port", "Client port"),
    server_port = ProtoField.uint16("rctp.transport.server_port", "Server port"),
    tag = ProtoField.uint32("rctp.transport.tag", "Data-stream tag", base.HEX),
    mode = ProtoField.string("rctp.transport.mode", "Mode"),
    stream = ProtoField.uint8("rctp.transport.stream", "Stream id"),
    reason = ProtoField.string("rctp.reason", "Reason"),
    allow = ProtoField.string("rctp.allow", "Allow"),
    user_agent = ProtoField.string("rctp.user_agent", "User-Agent"),
    server = ProtoField.string("rctp.server", "Server"),
    body = ProtoField.bytes("rctp.body", "Body"),
    text = ProtoField.string("rctp.body.text", "Body text"),
    request_in = ProtoField.framenum("rctp.request_in", "Request in frame", base.NONE,
        frametype.REQUEST),
    response_in = ProtoField.framenum("rctp.response_in", "Response in frame", base.NONE,
        frametype.RESPONSE),
    time = ProtoField.relative_time("rctp.time", "Time since the request"),
}
local CE = malformed_fields("rctp", "RCTP/2.0 message")
rctp.fields = {
    CF.method, CF.target, CF.version, CF.status, CF.phrase, CF.header, CF.cseq, CF.session,
    CF.session_id, CF.session_timeout, CF.content_length, CF.content_type, CF.nodes, CF.transport,
    CF.client_port, CF.server_port, CF.tag, CF.mode, CF.stream, CF.reason, CF.allow,
    CF.user_agent, CF.server, CF.body, CF.text, CF.request_in, CF.response_in, CF.time,
    CE.reason, CE.offset, CE.rule,
}
rctp.experts = {CE.expert, CE.warning, CE.note}
rctp.prefs.tcp_ports = Pref.range("TCP ports", C.ports, "TCP ports of RCTP/2.0 control", 65535)
rctp.prefs.heuristic = Pref.bool("Find RCTP/2.0 on any TCP port", true,
    "Try RCTP/2.0 on TCP connections of other ports, by their first line")

local f_tcp_stream = Field.new("tcp.stream")
local f_tcp_seq = Field.new("tcp.seq")
local f_tcp_completeness = Field.new("tcp.completeness")

local METHODS = {}
for _, method in ipairs(C.methods) do
    METHODS[method] = true
end
local HEAD_LIMIT = C.limits.start_line + 2 + C.limits.header_section + 4

-- Requests by connection, direction and CSeq, so that a response names its request.
local requests = {}

local function token(text)
    return text ~= "" and text:find("^[!#$%%&'*+%-.^_`|~0-9A-Za-z]+$") ~= nil
end

local function field_value_ok(text)
    -- field-vchar, SP and HTAB: no other control character (RFC 9110)
    return text:find("[%z\1-\8\10-\31\127]") == nil
end

local function direction_key(pinfo)
    return tostring(pinfo.src) .. ":" .. tostring(pinfo.src_port) .. ">" ..
        tostring(pinfo.dst) .. ":" .. tostring(pinfo.dst_port)
end

local function reverse_key(pinfo)
    return tostring(pinfo.dst) .. ":" .. tostring(pinfo.dst_port) .. ">" ..
        tostring(pinfo.src) .. ":" .. tostring(pinfo.src_port)
end

-- D-RCTP-4: CR only before LF, LF only after CR; the offset of the first fault, or nil. A CR
-- at the very end of what has come may yet be followed by its LF (`partial`).
local function line_ending_fault(raw, partial)
    local at = 1
    while true do
        local found = raw:find("[\r\n]", at)
        if found == nil then
            return nil
        end
        local char = raw:sub(found, found)
        if char == "\r" then
            if raw:sub(found + 1, found + 1) ~= "\n" then
                if not (partial and found == #raw) then
                    return found - 1
                end
            end
            at = found + 2
        else
            return found - 1 -- a LF not after a CR
        end
    end
end

local function parse_transport(item, value)
    local parts = {}
    for part in (value .. ";"):gmatch("([^;]*);") do
        parts[#parts + 1] = part:gsub("^[ \t]+", ""):gsub("[ \t]+$", "")
    end
    if parts[1] ~= "udp" then
        warn(CE, item, "Transport " .. parts[1] .. ": RCTP/2.0's data stream is udp", "R-RCTP-38")
        return
    end
    for index = 2, #parts do
        local key, text = parts[index]:match("^([^=]*)=(.*)$")
        local number = text and tonumber(text)
        if key == "client_port" and number then
            item:add(CF.client_port, number)
        elseif key == "server_port" and number then
            item:add(CF.server_port, number)
        elseif key == "tag" and text:find("^%x%x%x%x%x%x%x%x$") then
            item:add(CF.tag, tonumber(text, 16))
        elseif key == "mode" then
            item:add(CF.mode, text)
        elseif key == "stream" and number then
            item:add(CF.stream, number)
        else
            warn(CE, item, "Transport parameter " .. parts[index] .. " is not one of D-RCTP-18",
                "R-RCTP-38")
        end
    end
end

-- One message from `offset`. Returns the bytes it takes; or -(bytes missing), or
-- -DESEGMENT_ONE_MORE_SEGMENT, when more must come; or nil when it cannot be framed (the rest of
-- the connection's bytes in that direction have no known boundaries: D-RCTP-10).
local function dissect_message(tvb, pinfo, tree, offset, infos)
    local available = tvb:len() - offset
    local raw = tvb:raw(offset, math.min(available, HEAD_LIMIT + 1))
    local is_response = raw:sub(1, 5) == "RCTP/"
    local head_end = raw:find("\r\n\r\n", 1, true)
    local scan = raw
    if head_end ~= nil then
        scan = raw:sub(1, head_end - 1)
    end
    -- `told`: the offset the codec gives, where it is not that of the bytes at fault (a
    -- Content-Length is a fault of the whole message: offset 0).
    local function fail(at, length, reason, rule, told)
        local root = tree:add(rctp, span(tvb, offset, available))
        root:set_text("RCTP/2.0, cannot be framed: " .. reason)
        report(CE, root, tvb, offset + at, length, offset, reason, rule, told)
        infos[#infos + 1] = "[cannot be framed: " .. reason .. "]"
        return nil
    end
    local fault = line_ending_fault(scan, head_end == nil)
    if fault ~= nil then
        return fail(fault, 1, "a line ends in a bare CR or LF, not CRLF", "R-RCTP-1")
    end
    -- The first word must be a method token or RCTP's version: anything else is not RCTP.
    local first = scan:match("^[^ \r\n]*")
    if not is_response and (#first < #scan and not token(first)) then
        return fail(0, #first, "malformed request line (method SP target SP version)", nil)
    end
    if head_end == nil then
        local line_end = raw:find("\r\n", 1, true)
        if (line_end == nil and available > C.limits.start_line + 1) or
            (line_end ~= nil and line_end - 1 > C.limits.start_line) then
            return fail(0, available, "start line too long", "R-RCTP-16")
        end
        if line_end ~= nil and available - (line_end + 1) > C.limits.header_section + 4 then
            return fail(0, available, "header section too long", "R-RCTP-16")
        end
        return -DESEGMENT_ONE_MORE_SEGMENT
    end
    local head = raw:sub(1, head_end - 1)
    local lines = {}
    for line in (head .. "\r\n"):gmatch("(.-)\r\n") do
        lines[#lines + 1] = line
    end
    local start_line = lines[1]
    if #start_line > C.limits.start_line then
        return fail(0, #start_line, "start line too long", "R-RCTP-16")
    end
    if #head - #start_line - 2 > C.limits.header_section then
        return fail(0, #head, "header section too long", "R-RCTP-16")
    end
    local message = {}
    if is_response then
        local version, status, phrase = start_line:match("^([^ ]*) ([^ ]*) (.*)$")
        if version == nil or not version:find("^RCTP/%d+%.%d+$") or
            not status:find("^%d%d%d$") or not field_value_ok(phrase) then
            return fail(0, #start_line, "malformed status line", "R-RCTP-1")
        end
        message.version, message.status, message.phrase = version, tonumber(status), phrase
    else
        local parts = {}
        for part in (start_line .. " "):gmatch("([^ ]*) ") do
            parts[#parts + 1] = part
        end
        if #parts ~= 3 or not token(parts[1]) or parts[2] == "" then
            return fail(0, #start_line, "malformed request line (method SP target SP version)",
                nil)
        end
        -- "RCTP/" in any letter case parses (RFC 5234 quoted text); D-RCTP-30 then makes
        -- rctp/2.0 another version than RCTP/2.0 (505), which the warning below says.
        if not parts[3]:upper():find("^RCTP/%d+%.%d+$") then
            return fail(#parts[1] + #parts[2] + 2, #parts[3],
                parts[3]:sub(1, 20) .. " is not an RCTP version", "R-RCTP-2")
        end
        message.method, message.target, message.version = parts[1], parts[2], parts[3]
    end
    if #lines - 1 > C.limits.header_fields then
        return fail(#start_line + 2, #head - #start_line - 2,
            "more than " .. C.limits.header_fields .. " header fields", "R-RCTP-16")
    end
    local fields = {}
    local at = #start_line + 2
    for index = 2, #lines do
        local line = lines[index]
        if #line > C.limits.header_line then
            return fail(at, #line, "header line too long", "R-RCTP-16")
        end
        local lead = line:sub(1, 1)
        if lead == " " or lead == "\t" then
            return fail(at, #line, "obsolete line folding", "R-RCTP-1")
        end
        local name, value = line:match("^([^:]*):(.*)$")
        if name == nil or not token(name) then
            return fail(at, #line,
                'malformed header field (name ":" value, no space before the colon)', "R-RCTP-1")
        end
        value = value:gsub("^[ \t]+", ""):gsub("[ \t]+$", "")
        if not field_value_ok(value) then
            return fail(at + #name + 1, #line - #name - 1,
                "a control character in a header field value", nil)
        end
        fields[#fields + 1] = {name = name, lower = name:lower(), value = value, at = at,
            length = #line}
        at = at + #line + 2
    end
    -- D-RCTP-4: Content-Length frames every body; Transfer-Encoding is refused.
    local body_length = 0
    local lengths = 0
    for _, field in ipairs(fields) do
        if field.lower == "transfer-encoding" then
            return fail(field.at, field.length, "Transfer-Encoding is not used by RCTP/2.0",
                "R-RCTP-7", 0)
        end
        if field.lower == "content-length" then
            lengths = lengths + 1
            if lengths > 1 then
                return fail(field.at, field.length, "Content-Length is given more than once",
                    "R-RCTP-6", 0)
            end
            if not field.value:find("^%d+$") then
                return fail(field.at, field.length, "Content-Length is not a decimal number",
                    "R-RCTP-6", 0)
            end
            if #field.value > 10 then
                return fail(field.at, field.length, "Content-Length has " .. #field.value ..
                    " digits, more than the 10 of its grammar (1*10DIGIT)", "R-RCTP-6", 0)
            end
            body_length = tonumber(field.value)
            if body_length > C.limits.body then
                return fail(field.at, field.length, "body of " .. body_length ..
                    " bytes is above the limit of " .. C.limits.body, "R-RCTP-16", 0)
            end
        end
    end
    local total = head_end + 3 + body_length
    if total > available then
        return -(total - available)
    end

    -- The message is whole: show it.
    local root = tree:add(rctp, tvb:range(offset, total))
    local summary
    if is_response then
        summary = message.version .. " " .. message.status .. " " .. message.phrase
        root:add(CF.version, tvb:range(offset, #message.version), message.version)
        root:add(CF.status, tvb:range(offset + #message.version + 1, 3), message.status)
        root:add(CF.phrase, span(tvb, offset + #message.version + 5, #message.phrase),
            message.phrase)
        if message.version ~= C.version then
            warn(CE, root, "a response of version " .. message.version, "R-RCTP-2")
        end
    else
        summary = message.method .. " " .. message.target
        local m, t = #message.method, #message.target
        root:add(CF.method, tvb:range(offset, m), message.method)
        root:add(CF.target, tvb:range(offset + m + 1, t), message.target)
        root:add(CF.version, tvb:range(offset + m + t + 2, #message.version), message.version)
        if not METHODS[message.method] then
            warn(CE, root, message.method .. " is not a method of RCTP/2.0 (answered 501)",
                "R-RCTP-9")
        end
        if message.version ~= C.version then
            warn(CE, root, "version " .. message.version .. " (answered 505)", "R-RCTP-10")
        end
    end
    root:set_text("RCTP/2.0 " .. (is_response and "response: " or "request: ") .. summary)
    local seen = {}
    local cseq
    local content_type
    for _, field in ipairs(fields) do
        local range = tvb:range(offset + field.at, field.length)
        local value_range = span(tvb, offset + field.at + field.length - #field.value,
            #field.value)
        local item = root:add(CF.header, range, field.name .. ": " .. field.value)
        local lower = field.lower
        if C.once[lower] then
            if seen[lower] then
                warn(CE, item, field.name .. " appears more than once (answered 400)",
                    "R-RCTP-11")
            end
            seen[lower] = true
        end
        if lower == "cseq" then
            local number = field.value:find("^%d+$") and #field.value <= 10 and
                tonumber(field.value)
            if number and number >= 1 and number <= C.max_cseq then
                item:add(CF.cseq, value_range, number)
                cseq = cseq or number
            else
                warn(CE, item, "CSeq " .. field.value .. " is not a number from 1 to " ..
                    C.max_cseq, "R-RCTP-3")
            end
        elseif lower == "session" then
            local sub = item:add(CF.session, value_range, field.value)
            local id, rest = field.value:match("^([A-Za-z0-9$%-_.+]+)(.*)$")
            local timeout = rest and rest:match("^;[ \t]*timeout=(%d+)$")
            if id ~= nil and #id >= 8 and #id <= 64 and (rest == "" or
                (timeout ~= nil and #timeout <= 5)) then
                sub:add(CF.session_id, value_range, id)
                if timeout ~= nil then
                    sub:add(CF.session_timeout, value_range, tonumber(timeout))
                end
            else
                warn(CE, sub, "Session " .. field.value .. " is not id[;timeout=seconds]",
                    "R-RCTP-18")
            end
        elseif lower == "content-length" then
            item:add(CF.content_length, value_range, tonumber(field.value))
        elseif lower == "content-type" then
            item:add(CF.content_type, value_range, field.value)
            content_type = field.value
        elseif lower == "nodes" then
            item:add(CF.nodes, value_range, field.value)
        elseif lower == "transport" then
            parse_transport(item:add(CF.transport, value_range, field.value), field.value)
        elseif lower == "reason" then
            item:add(CF.reason, value_range, field.value)
        elseif lower == "allow" then
            item:add(CF.allow, value_range, field.value)
        elseif lower == "user-agent" then
            item:add(CF.user_agent, value_range, field.value)
        elseif lower == "server" then
            item:add(CF.server, value_range, field.value)
        end
    end
    if cseq ~= nil then
        summary = summary .. " CSeq " .. cseq
    elseif not is_response then
        warn(CE, root, "a request without CSeq (answered 400)", "R-RCTP-3")
    end
    if body_length > 0 then
        local body = tvb:range(offset + head_end + 3, body_length)
        local item = root:add(CF.body, body)
        if content_type == nil then
            warn(CE, item, "a body without Content-Type", "R-RCTP-6")
        elseif content_type:lower():find("^text/") then
            item:add(CF.text, body, body:raw())
        end
    end
    -- Which request a response answers (D-RCTP-6: its CSeq, in the other direction).
    local stream_field = f_tcp_stream()
    local connection = stream_field and tostring(stream_field.value) or "?"
    requests[connection] = requests[connection] or {}
    local known = requests[connection]
    if cseq ~= nil and not is_response then
        local key = direction_key(pinfo) .. "#" .. cseq
        if known[key] == nil or known[key].frame == pinfo.number then
            known[key] = known[key] or {frame = pinfo.number, time = pinfo.abs_ts}
            if known[key].answer ~= nil then
                root:add(CF.response_in, known[key].answer):set_generated()
            end
        end
    elseif cseq ~= nil then
        local key = reverse_key(pinfo) .. "#" .. cseq
        local request = known[key]
        if request ~= nil and request.frame <= pinfo.number then
            request.answer = request.answer or pinfo.number
            root:add(CF.request_in, request.frame):set_generated()
            local delta = pinfo.abs_ts - request.time
            local seconds = math.floor(delta)
            root:add(CF.time, NSTime.new(seconds, math.floor((delta - seconds) * 1e9 + 0.5)))
                :set_generated()
        end
    end
    infos[#infos + 1] = summary
    return total
end

-- Where each direction of each connection could not be framed: the frame, after which its
-- bytes have no known boundaries (D-RCTP-10).
local unframed = {}
-- Where each direction's first message starts: the frame. A capture may begin in the middle of
-- a connection, or a heuristic may find RCTP after the first bytes went by: until a segment
-- starts at the start of the stream (its SYN seen) or with a method or RCTP's version, its bytes
-- are the rest of a message whose start is not known, not a malformed one.
local synced = {}

local function starts_a_message(tvb)
    local stream_start = false
    local completeness = f_tcp_completeness()
    local sequence = f_tcp_seq()
    if completeness ~= nil and sequence ~= nil then
        stream_start = bit32.band(completeness.value, 1) ~= 0 and sequence.value == 1
    end
    local raw = tvb:raw(0, math.min(tvb:len(), 16))
    local word = raw:match("^([A-Z]+) ")
    return stream_start or raw:sub(1, 5) == "RCTP/" or (word ~= nil and METHODS[word] == true)
end

local function connection_of(pinfo)
    local stream_field = f_tcp_stream()
    return (stream_field and tostring(stream_field.value) or "?") .. " " .. direction_key(pinfo)
end

local function rctp_dissect(tvb, pinfo, tree)
    local length = tvb:len()
    local offset = 0
    local infos = {}
    local direction = connection_of(pinfo)
    local failed = unframed[direction]
    if failed ~= nil and failed < pinfo.number then
        local root = tree:add(rctp, tvb:range(0, length))
        root:set_text("RCTP/2.0, " .. plural(length, "byte") .. " after a message that could" ..
            " not be framed (frame " .. failed .. "): boundaries unknown (D-RCTP-10)")
        root:add_proto_expert_info(CE.note, "after a framing error in frame " .. failed)
        pinfo.cols.protocol = "RCTP"
        pinfo.cols.info = "[after a framing error]"
        return length
    end
    local first = synced[direction]
    if first == nil or pinfo.number < first then
        if not starts_a_message(tvb) then
            local root = tree:add(rctp, tvb:range(0, length))
            root:set_text("RCTP/2.0, " .. plural(length, "byte") .. " of a message that began" ..
                " before the capture (or before RCTP/2.0 was found on this connection)")
            root:add_proto_expert_info(CE.note, "the rest of a message whose start is not seen")
            pinfo.cols.protocol = "RCTP"
            pinfo.cols.info = "[continuation]"
            return length
        end
        synced[direction] = pinfo.number
    end
    while offset < length do
        local taken = dissect_message(tvb, pinfo, tree, offset, infos)
        if taken == nil then
            unframed[direction] = unframed[direction] or pinfo.number
            offset = length
        elseif taken < 0 then
            pinfo.desegment_offset = offset
            pinfo.desegment_len = -taken
            if offset == 0 then
                pinfo.cols.protocol = "RCTP"
                pinfo.cols.info = "[RCTP/2.0 message, continued in the next segment]"
                return length
            end
            break
        else
            offset = offset + taken
        end
    end
    pinfo.cols.protocol = "RCTP"
    pinfo.cols.info = table.concat(infos, ", ")
    return length
end

function rctp.dissector(tvb, pinfo, tree)
    return rctp_dissect(tvb, pinfo, tree)
end

-- A new capture, or the same read again: what was learnt of the last one is forgotten.
function rctp.init()
    requests = {}
    unframed = {}
    synced = {}
end

local function rctp_heuristic(tvb, pinfo, tree)
    if not rctp.prefs.heuristic or tvb:len() < 3 then
        return false
    end
    -- A method of RCTP/2.0 and a space, or a status line's version: the start of a message.
    local raw = tvb:raw(0, math.min(tvb:len(), 32))
    local word = raw:match("^([A-Z]+) ")
    if not (raw:sub(1, 5) == "RCTP/" or (word ~= nil and METHODS[word])) then
        return false
    end
    pinfo.conversation = rctp -- the rest of the connection, whatever its segments hold
    rctp_dissect(tvb, pinfo, tree)
    return true
end

-- The RCTP/2.0 data stream (UDP) -------------------------------------------------------------

local ds = Proto("rctpds", "RCTP/2.0 data stream")
local DF = {
    version = ProtoField.uint8("rctpds.version", "Version"),
    count = ProtoField.uint8("rctpds.count", "Payload count"),
    seq = ProtoField.uint16("rctpds.seq", "Sequence number"),
    tag = ProtoField.uint32("rctpds.tag", "Session tag", base.HEX),
    timestamp = ProtoField.uint64("rctpds.timestamp", "Timestamp (NTP)", base.HEX),
    time = ProtoField.absolute_time("rctpds.time", "Sent at (sender's clock)", base.UTC),
    payload = ProtoField.none("rctpds.payload", "Payload"),
    type = ProtoField.uint8("rctpds.payload.type", "Payload type", base.DEC, D.payload_types),
    stream = ProtoField.uint8("rctpds.payload.stream", "Stream id"),
    length = ProtoField.uint16("rctpds.payload.length", "Body length"),
    data = ProtoField.bytes("rctpds.data", "DATA body (the stream's values)"),
    unknown = ProtoField.bytes("rctpds.unknown", "Body of an unknown payload type"),
    message = ProtoField.uint8("rctpds.flow.message", "FLOW message", base.DEC, D.messages),
    operation = ProtoField.uint8("rctpds.flow.operation", "Operation", base.DEC, D.operations),
    request_id = ProtoField.uint16("rctpds.flow.request_id", "Request id"),
    fields = ProtoField.bytes("rctpds.flow.fields", "Fields of an operation not known"),
    body = ProtoField.bytes("rctpds.flow.body", "FLOW body"),
}
local DE = malformed_fields("rctpds", "RCTP/2.0 data-stream packet")
local ds_fields = {
    DF.version, DF.count, DF.seq, DF.tag, DF.timestamp, DF.time, DF.payload, DF.type, DF.stream,
    DF.length, DF.data, DF.unknown, DF.message, DF.operation, DF.request_id, DF.fields, DF.body,
    DE.reason, DE.offset, DE.rule,
}
-- The fields of the FLOW layouts (D-RCTP-22), as the codec names them.
local FLOW = {}
for _, field in ipairs(D.flow_fields) do
    local abbr = "rctpds.flow." .. field.name
    local entry = {field = field}
    if field.kind == "time" then
        entry.raw = ProtoField.uint64(abbr, field.label .. " (NTP)", base.HEX)
        entry.time = ProtoField.absolute_time(abbr .. "_time", field.label, base.UTC)
        ds_fields[#ds_fields + 1] = entry.raw
        ds_fields[#ds_fields + 1] = entry.time
    elseif field.kind == "enum" then
        entry.raw = ProtoField.uint8(abbr, field.label, base.DEC, D.enums[field.enum])
        ds_fields[#ds_fields + 1] = entry.raw
    else
        entry.raw = ProtoField.uint32(abbr, field.label .. " (microseconds)")
        ds_fields[#ds_fields + 1] = entry.raw
    end
    FLOW[field.name] = entry
end
ds.fields = ds_fields
ds.experts = {DE.expert, DE.warning, DE.note}
ds.prefs.udp_ports = Pref.range("UDP ports", D.ports,
    "UDP ports of the RCTP/2.0 data stream (negotiated by SETUP; the reference server's is its RCTP port)",
    65535)
ds.prefs.heuristic = Pref.bool("Find the data stream on any UDP port", true,
    "Take UDP datagrams of other ports whose header and payloads fit D-RCTP-19")

local function flow_label(message, operation, request_id)
    return describe(D.operations, operation) .. " " .. describe(D.messages, message) ..
        " #" .. request_id
end

-- A FLOW body (D-RCTP-22) at `at`, `length` bytes; a body that breaks its layout is malformed
-- (R-RCTP-52) but leaves the packet readable.
local function dissect_flow(tvb, raw, tree, at, length)
    local function bad(where, size, reason)
        tree:add(DF.body, span(tvb, at, length))
        report(DE, tree, tvb, where, size, 0, reason, D.flow_rule)
        return "FLOW (malformed)"
    end
    if length < D.preamble then
        return bad(at, length, "FLOW body of " .. plural(length, "byte") ..
            ", shorter than its preamble")
    end
    local message = u8(raw, at)
    local operation = u8(raw, at + 1)
    local request_id = u16(raw, at + 2)
    local layout = D.layouts[message * 256 + operation] or D.any_operation[message]
    if layout == nil then
        if D.messages[message] == nil then
            return bad(at, 1, "FLOW message " .. message .. " is none of " .. choices(D.messages))
        end
        return bad(at + 1, 1, D.message_names[message] .. " of operation " .. operation ..
            ", none of " .. choices(D.operations))
    end
    tree:add(DF.message, tvb:range(at, 1))
    tree:add(DF.operation, tvb:range(at + 1, 1))
    tree:add(DF.request_id, tvb:range(at + 2, 2))
    local label = flow_label(message, operation, request_id)
    local start = at + D.preamble
    local size = length - D.preamble
    if layout.fields == nil then -- a request of an operation this side does not know
        if size > 0 then
            tree:add(DF.fields, tvb:range(start, size))
        end
        return label
    end
    if size ~= layout.size then
        local where = start
        if size > layout.size then
            where = start + layout.size
        end
        return bad(where, math.abs(size - layout.size), layout.name .. " has " ..
            plural(size, "byte") .. " of fields, not " .. layout.size)
    end
    local position = start
    for _, name in ipairs(layout.fields) do
        local entry = FLOW[name]
        local width = entry.field.size
        local range = tvb:range(position, width)
        if entry.field.kind == "enum" then
            local value = u8(raw, position)
            if D.enums[entry.field.enum][value] == nil then
                return bad(position, 1, name .. " " .. value .. " is none of " ..
                    choices(D.enums[entry.field.enum]))
            end
        end
        tree:add(entry.raw, range)
        if entry.time ~= nil then
            tree:add_packet_field(entry.time, range, ENC_TIME_NTP + ENC_BIG_ENDIAN)
        end
        position = position + width
    end
    return label
end

local function ds_dissect(tvb, pinfo, tree)
    local size = tvb:len()
    pinfo.cols.protocol = "RCTP-DS"
    local root = tree:add(ds, tvb:range(0, size))
    local function bad(at, length, reason)
        report(DE, root, tvb, at, length, 0, reason, D.rule)
        pinfo.cols.info = "Malformed: " .. reason
        return size
    end
    if size > D.max_datagram then
        return bad(D.max_datagram, size - D.max_datagram, "datagram of " .. size ..
            " bytes, more than " .. D.max_datagram)
    end
    local raw = tvb:raw()
    if size > 0 and u8(raw, 0) ~= D.version then
        return bad(0, 1, "version " .. u8(raw, 0) .. ", not " .. D.version)
    end
    if size < D.header then
        return bad(size, 0, "header of " .. size .. " bytes, not " .. D.header)
    end
    root:add(DF.version, tvb:range(0, 1))
    root:add(DF.count, tvb:range(1, 1))
    root:add(DF.seq, tvb:range(2, 2))
    root:add(DF.tag, tvb:range(4, 4))
    root:add(DF.timestamp, tvb:range(8, 8))
    root:add_packet_field(DF.time, tvb:range(8, 8), ENC_TIME_NTP + ENC_BIG_ENDIAN)
    local count = u8(raw, 1)
    local sequence = u16(raw, 2)
    root:append_text(", seq " .. sequence)
    pinfo.cols.info = "seq " .. sequence
    if count == 0 then
        return bad(1, 1, "payload count 0: a packet holds 1 to " .. D.max_payloads .. " payloads")
    end
    local infos = {}
    local position = D.header
    for index = 1, count do
        local left = size - position - D.payload_header
        if left < 0 then
            return bad(position, size - position, "payload " .. index .. " of " .. count ..
                " has " .. (size - position) .. " of " .. D.payload_header .. " header bytes")
        end
        local kind = u8(raw, position)
        local stream = u8(raw, position + 1)
        local length = u16(raw, position + 2)
        local item = root:add(DF.payload, span(tvb, position, D.payload_header + length))
        item:add(DF.type, tvb:range(position, 1))
        item:add(DF.stream, tvb:range(position + 1, 1))
        item:add(DF.length, tvb:range(position + 2, 2))
        if length > left then
            item:set_text("Payload " .. index .. ": " .. describe(D.payload_types, kind))
            return bad(position + 2, 2, "payload " .. index .. " of " .. count ..
                ": body length " .. length .. " runs past the end (" .. plural(left, "byte") ..
                " left)")
        end
        local body = position + D.payload_header
        local text
        if kind == D.DATA then
            add_bytes(item, DF.data, tvb, body, length, "DATA body")
            text = "DATA " .. stream
        elseif kind == D.FLOW then
            text = dissect_flow(tvb, raw, item, body, length)
        else
            local unknown = add_bytes(item, DF.unknown, tvb, body, length, "Body")
            unknown:add_proto_expert_info(DE.note,
                "payload type " .. kind .. " is not known: skipped by its length (R-RCTP-51)")
            text = "type " .. kind
        end
        item:set_text("Payload " .. index .. ": " .. text .. ", stream " .. stream .. ", " ..
            plural(length, "byte"))
        infos[#infos + 1] = text
        position = body + length
    end
    if position < size then
        return bad(position, size - position, plural(size - position, "byte") ..
            " after the last of " .. plural(count, "payload"))
    end
    pinfo.cols.info = "seq " .. sequence .. ": " .. table.concat(infos, ", ")
    return size
end

function ds.dissector(tvb, pinfo, tree)
    return ds_dissect(tvb, pinfo, tree)
end

-- D-RCTP-19's framing, exactly: version 2, 1 to 255 payloads filling the datagram.
local function ds_fits(tvb)
    local size = tvb:len()
    if size < D.header + D.payload_header then
        return false
    end
    local raw = tvb:raw()
    if u8(raw, 0) ~= D.version then
        return false
    end
    local count = u8(raw, 1)
    if count == 0 then
        return false
    end
    local position = D.header
    for _ = 1, count do
        if size - position < D.payload_header then
            return false
        end
        position = position + D.payload_header + u16(raw, position + 2)
    end
    return position == size
end

local function ds_heuristic(tvb, pinfo, tree)
    if not ds.prefs.heuristic or not ds_fits(tvb) then
        return false
    end
    pinfo.conversation = ds
    ds_dissect(tvb, pinfo, tree)
    return true
end

-- RSP (UDP) ----------------------------------------------------------------------------------

local rsp = Proto("rcmlrsp", "Robot Simulacrum Protocol (RSP)")
local RF = {
    version = ProtoField.uint8("rcmlrsp.version", "Version"),
    model_id = ProtoField.uint16("rcmlrsp.model_id", "Model ID"),
    encryption = ProtoField.uint8("rcmlrsp.encryption", "Encryption", base.DEC, R.encryptions),
    type = ProtoField.uint8("rcmlrsp.type", "Packet type", base.DEC, R.types),
    seq = ProtoField.uint16("rcmlrsp.seq", "Sequence number"),
    timestamp = ProtoField.uint32("rcmlrsp.timestamp", "Timestamp (ms since the sender's first)"),
    session_id = ProtoField.uint64("rcmlrsp.session_id", "Session ID", base.HEX),
    last_received = ProtoField.uint16("rcmlrsp.last_received", "Last received sequence number"),
    buffer = ProtoField.uint8("rcmlrsp.buffer", "Buffer", base.HEX),
    clear_buffer = ProtoField.bool("rcmlrsp.clear_buffer", "Clear Buffer", 8, nil, R.clear_buffer),
    free_buffers = ProtoField.uint8("rcmlrsp.free_buffers", "Free memory-command buffers"),
    client_nonce = ProtoField.bytes("rcmlrsp.client_nonce", "Client nonce"),
    robot_nonce = ProtoField.bytes("rcmlrsp.robot_nonce", "Robot nonce"),
    period_ms = ProtoField.uint16("rcmlrsp.period", "Period (ms)"),
    mac = ProtoField.bytes("rcmlrsp.mac", "MAC"),
    refused = ProtoField.uint8("rcmlrsp.refused_reason", "Refused because", base.DEC,
        R.refused_reasons),
    bye = ProtoField.uint8("rcmlrsp.bye_reason", "Bye reason", base.DEC, R.bye_reasons),
    sealed = ProtoField.bytes("rcmlrsp.ciphertext", "Encrypted body"),
    auth_tag = ProtoField.bytes("rcmlrsp.auth_tag", "Authentication tag"),
    payload = ProtoField.bytes("rcmlrsp.payload", "Device Map and payloads (no model given)"),
    map = ProtoField.bytes("rcmlrsp.map", "Device Map"),
    device = ProtoField.string("rcmlrsp.device", "Device"),
    id = ProtoField.uint16("rcmlrsp.id", "Occurrence ID"),
}
local RE = malformed_fields("rcmlrsp", "RSP packet")
local rsp_fields = {
    RF.version, RF.model_id, RF.encryption, RF.type, RF.seq, RF.timestamp, RF.session_id,
    RF.last_received, RF.buffer, RF.clear_buffer, RF.free_buffers, RF.client_nonce,
    RF.robot_nonce, RF.period_ms, RF.mac, RF.refused, RF.bye, RF.sealed, RF.auth_tag, RF.payload,
    RF.map, RF.device, RF.id, RE.reason, RE.offset, RE.rule,
}
-- The body part fields, by the codec's names.
local PARTS = {
    client_nonce = RF.client_nonce, robot_nonce = RF.robot_nonce, period_ms = RF.period_ms,
    mac = RF.mac, REFUSED = RF.refused, BYE = RF.bye,
}

-- The model's devices and fields (D-RSP-14, D-RSP-4), when one was given.
local FIELD_MAKERS = {
    bool = ProtoField.bool, int8 = ProtoField.int8, uint8 = ProtoField.uint8,
    int16 = ProtoField.int16, uint16 = ProtoField.uint16, int32 = ProtoField.int32,
    uint32 = ProtoField.uint32, int64 = ProtoField.int64, uint64 = ProtoField.uint64,
    float32 = ProtoField.float, float64 = ProtoField.double, string = ProtoField.string,
    bytes = ProtoField.bytes,
}
if M ~= nil then
    for _, device in ipairs(M.devices) do
        device.bit_field = ProtoField.bool("rcmlrsp.map." .. device.abbr, device.name, 8, nil,
            bit32.rshift(0x80, device.position % 8))
        device.texts = {}
        -- The payload's size in each packet, when its fields all have one size (else nil).
        device.sizes = {}
        local fields_size = 0
        for _, field in ipairs(device.fields) do
            local kind = GEN.types[field.type]
            if fields_size ~= nil and not kind.sized then
                fields_size = fields_size + kind.width * (field.count or 1)
            else
                fields_size = nil
            end
        end
        for kind, meaning in pairs(device.bits) do
            device.texts[kind] = "Device: " .. device.name .. " (" .. device.kind .. ", " ..
                meaning .. ")"
            local size = 0
            if meaning == "occurrence" or meaning == "id" then
                size = M.id_length
            end
            if meaning == "state" or meaning == "occurrence" then
                size = fields_size and (size + fields_size)
            end
            device.sizes[kind] = size
        end
        rsp_fields[#rsp_fields + 1] = device.bit_field
        for _, field in ipairs(device.fields) do
            local label = field.name
            if field.unit ~= nil then
                label = label .. " (" .. field.unit .. ")"
            end
            field.proto_field = FIELD_MAKERS[field.type](
                "rcmlrsp.dev." .. device.abbr .. "." .. field.abbr, label)
            rsp_fields[#rsp_fields + 1] = field.proto_field
        end
    end
end
rsp.fields = rsp_fields
rsp.experts = {RE.expert, RE.warning, RE.note}
rsp.prefs.udp_ports = Pref.range("UDP ports", R.ports, "UDP ports of RSP robots", 65535)
rsp.prefs.heuristic = Pref.bool("Find RSP on any UDP port", true,
    "Take UDP datagrams of other ports whose header fits D-RSP-10")

local ZERO_SESSION = string.rep("\0", 6)

-- D-RSP-10's buffer byte from each sender.
local function buffer_ok(sender, byte)
    local robot = byte <= (M and M.command_buffers or R.max_free_buffers)
    local local_ = byte == 0 or byte == R.clear_buffer
    if sender == "local" then
        return local_
    elseif sender == "robot" then
        return robot
    end
    return local_ or robot
end

-- Whether UTF-8 `text` is valid; else the offset of the first byte that is not.
local function utf8_fault(text)
    local index, size = 1, #text
    while index <= size do
        local byte = text:byte(index)
        local need, low, high = 0, 0x80, 0xBF
        if byte < 0x80 then
            need = 0
        elseif byte >= 0xC2 and byte <= 0xDF then
            need = 1
        elseif byte == 0xE0 then
            need, low = 2, 0xA0
        elseif (byte >= 0xE1 and byte <= 0xEC) or byte == 0xEE or byte == 0xEF then
            need = 2
        elseif byte == 0xED then
            need, high = 2, 0x9F
        elseif byte == 0xF0 then
            need, low = 3, 0x90
        elseif byte >= 0xF1 and byte <= 0xF3 then
            need = 3
        elseif byte == 0xF4 then
            need, high = 3, 0x8F
        else
            return index - 1
        end
        for extra = 1, need do
            local next_byte = text:byte(index + extra)
            if next_byte == nil then
                return index - 1
            end
            if extra == 1 and (next_byte < low or next_byte > high) then
                return index - 1
            end
            if extra > 1 and (next_byte < 0x80 or next_byte > 0xBF) then
                return index - 1
            end
        end
        index = index + need + 1
    end
    return nil
end

-- A fault in a payload, raised as an error object and reported by the packet's dissector.
local Fault = {}
local function fault(at, length, reason, rule)
    error(setmetatable({at = at, length = length, reason = reason, rule = rule}, Fault), 0)
end

local function need(raw, at, count, what)
    local left = #raw - at
    if left < count then
        fault(at, left, what .. ": truncated: " .. count .. " bytes needed, " .. left .. " left",
            R.body_rule)
    end
end

local function outside(field, value)
    -- Written as "not within", so that NaN, which compares false, is outside too.
    if field.min ~= nil and not (value >= field.min) then
        return true
    end
    return field.max ~= nil and not (value <= field.max)
end

-- One field's value at `at` (D-RCML-10, D-RCML-11); the offset after it.
local function pull_field(tvb, raw, tree, device, field, at)
    local kind = GEN.types[field.type]
    local count = field.count or 1
    local what = device.name
    if kind.sized then
        for _ = 1, count do
            need(raw, at, 2, what)
            local length = u16(raw, at)
            if length > field.size then
                fault(at, 2, what .. ": length " .. length .. " exceeds size " .. field.size,
                    GEN.value_rule)
            end
            need(raw, at + 2, length, what)
            if field.type == "string" then
                local text = raw:sub(at + 3, at + 2 + length)
                local bad = utf8_fault(text)
                if bad ~= nil then
                    fault(at + 2 + bad, 1, what .. ": string is not UTF-8", GEN.value_rule)
                end
                tree:add(field.proto_field, span(tvb, at, 2 + length), text)
            else
                add_bytes(tree, field.proto_field, tvb, at + 2, length, field.name)
            end
            at = at + 2 + length
        end
        return at
    end
    local width = kind.width
    need(raw, at, width * count, what)
    local start = at
    if field.type == "bool" then
        for index = 0, count - 1 do
            local value = u8(raw, at + index)
            if value > 1 then
                fault(at + index, 1, what .. ": bool byte " .. string.format("0x%02x", value) ..
                    " is neither 0x00 nor 0x01", GEN.value_rule)
            end
        end
    end
    local values = {}
    for index = 0, count - 1 do
        local range = tvb:range(at + index * width, width)
        local value
        if field.type == "bool" then
            value = u8(raw, at + index) == 1
            tree:add(field.proto_field, range, value)
        else
            if field.min == nil and field.max == nil then
                value = 0 -- not compared: not read
            elseif kind.kind == "float" then
                value = range:float()
            elseif width == 8 and kind.signed then
                value = range:int64()
            elseif width == 8 then
                value = range:uint64()
            elseif kind.signed then
                value = range:int()
            else
                value = range:uint()
            end
            tree:add(field.proto_field, range)
        end
        values[#values + 1] = value
    end
    if field.min ~= nil or field.max ~= nil then
        for index, value in ipairs(values) do
            if outside(field, value) then
                fault(start + (index - 1) * width, width, what .. "/" .. field.name .. ": " ..
                    tostring(value) .. " is outside " .. field.min_text .. " to " ..
                    field.max_text, R.body_rule)
            end
        end
    end
    return at + width * count
end

-- DOWNLINK, UPLINK and ACK bodies with the model: the Device Map, then the payloads of its set
-- bits in model order (D-RSP-14).
local function dissect_map_body(tvb, raw, root, kind, at)
    local size = tvb:len()
    local map_size = M.map_size
    if size - at < map_size then
        fault(size, 0, "Device Map of " .. (size - at) .. " bytes, not " .. map_size, R.body_rule)
    end
    local map_item = root:add(RF.map, tvb:range(at, map_size))
    local set = {}
    local bytes = {byte(raw, at + 1, at + map_size)}
    for index = 1, map_size do
        local value = bytes[index]
        local position = (index - 1) * 8
        while value ~= 0 do
            if value >= 0x80 then
                local device = M.devices[position + 1]
                if device == nil then
                    fault(at + index - 1, 1, "bit " .. position .. " is set, past the model's " ..
                        #M.devices .. " devices", R.map_rule)
                end
                if device.bits[kind] == "never" then
                    fault(at + index - 1, 1, device.name .. "'s bit is never set in " .. kind ..
                        " (D-RSP-14)", R.map_rule)
                end
                set[#set + 1] = device
            end
            value = (value * 2) % 256
            position = position + 1
        end
    end
    -- The set bits, each over its map byte (one TvbRange a byte).
    local ranges = {}
    for _, device in ipairs(set) do
        local index = math.floor(device.position / 8)
        ranges[index] = ranges[index] or tvb:range(at + index, 1)
        map_item:add(device.bit_field, ranges[index])
    end
    local position = at + map_size
    local names = {}
    for _, device in ipairs(set) do
        local meaning = device.bits[kind]
        local start = position
        local known = device.sizes[kind]
        local whole = known ~= nil and size - position >= known
        local item = root:add(RF.device, tvb:range(position, whole and known or 0), device.name,
            device.texts[kind])
        if meaning == "occurrence" or meaning == "id" then
            need(raw, position, M.id_length, device.name)
            item:add(RF.id, tvb:range(position, M.id_length))
            position = position + M.id_length
        end
        if meaning == "state" or meaning == "occurrence" then
            for _, field in ipairs(device.fields) do
                position = pull_field(tvb, raw, item, device, field, position)
            end
        end
        if not whole then
            item:set_len(position - start)
        end
        names[#names + 1] = device.name
    end
    if position < size then
        fault(position, size - position, (size - position) .. " bytes after the last payload",
            R.body_rule)
    end
    return table.concat(names, " ")
end

-- A session body (HELLO, WELCOME, REFUSED, BYE, PERIOD): its parts in order.
local function dissect_session_body(tvb, raw, root, header, at)
    local parts = R.bodies[header.type]
    local layout = {}
    for _, part in ipairs(parts.parts) do
        layout[#layout + 1] = part
    end
    if parts.signed and header.encryption ~= 0 then
        layout[#layout + 1] = R.mac_part
    end
    local position = at
    local size = tvb:len()
    local texts = {}
    for _, part in ipairs(layout) do
        if size - position < part.size then
            fault(position, size - position, parts.name .. " body cut short: truncated: " ..
                part.size .. " bytes needed, " .. (size - position) .. " left", R.body_rule)
        end
        if part.kind == "period" then
            local value = u16(raw, position)
            if value < R.min_period_ms or value > R.max_period_ms then
                fault(position, part.size, "period " .. value .. " ms is outside " ..
                    R.min_period_ms .. " to " .. R.max_period_ms .. " (D-RSP-13)", R.body_rule)
            end
            texts[#texts + 1] = "T = " .. value .. " ms"
        elseif part.kind == "reason" then
            local value = u8(raw, position)
            if part.names[value] == nil then
                fault(position, part.size, part.enum .. " " .. value .. " is none of " ..
                    choices(part.names), R.body_rule)
            end
            texts[#texts + 1] = part.names[value]
        end
        root:add(PARTS[part.name] or PARTS[R.types[header.type]], tvb:range(position, part.size))
        position = position + part.size
    end
    if position < size then
        fault(position, size - position, (size - position) .. " bytes after the " .. parts.name ..
            " body", R.body_rule)
    end
    return table.concat(texts, " ")
end

-- The body after a header that holds: what the info column says of it, or a Fault raised.
local function dissect_rsp_body(tvb, raw, root, header, name, size)
    if header.encryption ~= 0 and not R.plaintext[header.type] then
        local sealed = size - R.header
        if sealed < R.tag_size then
            fault(R.header, sealed, "sealed body of " .. plural(sealed, "byte") ..
                ", shorter than its " .. R.tag_size .. "-byte tag", R.sealed_rule)
        end
        if sealed > R.tag_size then
            root:add(RF.sealed, tvb:range(R.header, sealed - R.tag_size))
        end
        root:add(RF.auth_tag, tvb:range(size - R.tag_size, R.tag_size))
        return "(encrypted)"
    end
    if R.map_types[header.type] then
        if M == nil then
            if size > R.header then
                root:add(RF.payload, tvb:range(R.header, size - R.header))
            end
            return "(no model given: payloads not decoded)"
        end
        return dissect_map_body(tvb, raw, root, name, R.header)
    end
    return dissect_session_body(tvb, raw, root, header, R.header)
end

local function rsp_dissect(tvb, pinfo, tree)
    local size = tvb:len()
    pinfo.cols.protocol = "RSP"
    local root = tree:add(rsp, tvb:range(0, size))
    local function bad(at, length, reason, rule)
        report(RE, root, tvb, at, length, 0, reason, rule)
        pinfo.cols.info = "Malformed: " .. reason
        return size
    end
    local raw = tvb:raw()
    if size < R.header then
        if size > 0 and u8(raw, 0) ~= R.version then
            return bad(0, 1, "version " .. u8(raw, 0) .. ", not " .. R.version, R.header_rule)
        end
        return bad(size, 0, "header of " .. size .. " bytes, not " .. R.header, R.header_rule)
    end
    local header = {
        version = u8(raw, 0), model_id = u16(raw, 1), encryption = u8(raw, 3), type = u8(raw, 4),
        sequence = u16(raw, 5), buffer = u8(raw, 19),
        session_zero = raw:sub(12, 17) == ZERO_SESSION,
    }
    root:add(RF.version, tvb:range(0, 1))
    root:add(RF.model_id, tvb:range(1, 2))
    root:add(RF.encryption, tvb:range(3, 1))
    root:add(RF.type, tvb:range(4, 1))
    root:add(RF.seq, tvb:range(5, 2))
    root:add(RF.timestamp, tvb:range(7, 4))
    root:add(RF.session_id, tvb:range(11, 6))
    root:add(RF.last_received, tvb:range(17, 2))
    local buffer_range = tvb:range(19, 1)
    local buffer = root:add(RF.buffer, buffer_range)
    local sender = R.senders[header.type]
    if sender == "local" or sender == "either" then
        buffer:add(RF.clear_buffer, buffer_range)
    end
    if sender == "robot" or sender == "either" then
        buffer:add(RF.free_buffers, buffer_range, header.buffer)
    end
    local name = describe(R.types, header.type)
    root:append_text(", " .. name .. ", seq " .. header.sequence)
    -- R-RSP-13, field by field in their order: the first fault in the bytes is the one told.
    if header.version ~= R.version then
        return bad(0, 1, "version " .. header.version .. ", not " .. R.version, R.header_rule)
    end
    if M ~= nil and header.model_id ~= M.model_id then
        return bad(1, 2, "model ID " .. header.model_id .. ", not this model's " .. M.model_id,
            R.header_rule)
    end
    if header.model_id < 1 then
        return bad(1, 2, "model ID " .. header.model_id .. " is no model's (1 to " ..
            R.max_model_id .. ")", R.header_rule)
    end
    if R.encryptions[header.encryption] == nil then
        return bad(3, 1, "encryption " .. header.encryption .. " is none of " ..
            R.encryption_list, R.header_rule)
    end
    if sender == nil then
        return bad(4, 1, "packet type " .. header.type .. " is none of 1 to " .. R.type_count,
            R.header_rule)
    end
    if header.session_zero ~= (R.without_session[header.type] == true) then
        local needed = "not 0"
        if R.without_session[header.type] then
            needed = "0"
        end
        return bad(11, 6, "the session ID of " .. name .. " is " .. needed .. ", not " ..
            tostring(tvb:range(11, 6):uint64()), R.header_rule)
    end
    if not buffer_ok(sender, header.buffer) then
        return bad(19, 1, "buffer byte " .. string.format("0x%02x", header.buffer) ..
            " is not one " .. name .. "'s sender gives", R.header_rule)
    end
    local ok, result = pcall(dissect_rsp_body, tvb, raw, root, header, name, size)
    if not ok then
        if getmetatable(result) ~= Fault then
            error(result, 0)
        end
        return bad(result.at, result.length, result.reason, result.rule)
    end
    if result ~= "" then
        pinfo.cols.info = name .. " seq " .. header.sequence .. ": " .. result
    else
        pinfo.cols.info = name .. " seq " .. header.sequence
    end
    return size
end

function rsp.dissector(tvb, pinfo, tree)
    return rsp_dissect(tvb, pinfo, tree)
end

local function rsp_heuristic(tvb, pinfo, tree)
    if not rsp.prefs.heuristic or tvb:len() < R.header then
        return false
    end
    local raw = tvb:raw(0, R.header)
    local model_id = u16(raw, 1)
    local kind = u8(raw, 4)
    if u8(raw, 0) ~= R.version or R.senders[kind] == nil or R.encryptions[u8(raw, 3)] == nil or
        model_id == 0 or (M ~= nil and model_id ~= M.model_id) then
        return false
    end
    local zero = raw:sub(12, 17) == ZERO_SESSION
    if zero ~= (R.without_session[kind] == true) then
        return false
    end
    pinfo.conversation = rsp
    rsp_dissect(tvb, pinfo, tree)
    return true
end

-- Registration --------------------------------------------------------------------------------

register_ports("tcp.port", rctp, nil, C.ports)
register_ports("udp.port", ds, nil, D.ports)
register_ports("udp.port", rsp, nil, R.ports)
rctp:register_heuristic("tcp", rctp_heuristic)
ds:register_heuristic("udp", ds_heuristic)
rsp:register_heuristic("udp", rsp_heuristic)

local current = {rctp = C.ports, ds = D.ports, rsp = R.ports}

function rctp.prefs_changed()
    local new = tostring(rctp.prefs.tcp_ports)
    if new ~= current.rctp then
        register_ports("tcp.port", rctp, current.rctp, new)
        current.rctp = new
    end
end

function ds.prefs_changed()
    local new = tostring(ds.prefs.udp_ports)
    if new ~= current.ds then
        register_ports("udp.port", ds, current.ds, new)
        current.ds = new
    end
end

function rsp.prefs_changed()
    local new = tostring(rsp.prefs.udp_ports)
    if new ~= current.rsp then
        register_ports("udp.port", rsp, current.rsp, new)
        current.rsp = new
    end
end
