// The gRPC services over grpc-web on the page's own origin (cncd serves both), with the
// operator's token as `authorization: Bearer` on every call, exactly as any other client.
import { createClient, type Interceptor } from "@connectrpc/connect";
import { createGrpcWebTransport } from "@connectrpc/connect-web";
import { Constants, Machine, Offsets, Plc, Preview, Programs } from "./gen/cnc/v1/cnc_pb";
import { token } from "./session";

const bearer: Interceptor = (next) => async (req) => {
  const t = token();
  if (t) req.header.set("authorization", `Bearer ${t}`);
  return await next(req);
};

/** cncd's error details (`grpc-status-details-bin`) are a bare `Diagnostics` message, not the
 * `google.rpc.Status` grpc-web clients expect (docs/api.md): the page reads them itself from
 * DIAGNOSTICS_HEADER instead of letting the client misread them. */
export const DIAGNOSTICS_HEADER = "x-cnc-diagnostics-bin";
const cncFetch: typeof fetch = async (input, init) => {
  const r = await fetch(input, init);
  const details = r.headers.get("grpc-status-details-bin");
  if (!details) return r;
  const headers = new Headers(r.headers);
  headers.delete("grpc-status-details-bin");
  headers.set(DIAGNOSTICS_HEADER, details);
  return new Response(r.body, { status: r.status, statusText: r.statusText, headers });
};

const transport = createGrpcWebTransport({
  baseUrl: location.origin,
  interceptors: [bearer],
  fetch: cncFetch,
});

export const machine = createClient(Machine, transport);
export const programs = createClient(Programs, transport);
export const offsets = createClient(Offsets, transport);
export const plc = createClient(Plc, transport);
export const constants = createClient(Constants, transport);
export const preview = createClient(Preview, transport);
